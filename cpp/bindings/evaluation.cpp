#include "bindings.hpp"

namespace nbv::bind {

void init_evaluation(py::module_& m) { (void)m; }

}  // namespace nbv::bind
