#include "bindings.hpp"

namespace nbv::bind {

void init_cloud(py::module_& m) { (void)m; }

}  // namespace nbv::bind
