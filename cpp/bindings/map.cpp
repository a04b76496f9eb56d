#include "bindings.hpp"

namespace nbv::bind {

void init_map(py::module_& m) { (void)m; }

}  // namespace nbv::bind
