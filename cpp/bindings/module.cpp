// nbvkit._core: the compiled core. Lists the binding units, one per concept.
#include "bindings.hpp"

PYBIND11_MODULE(_core, m) {
  m.doc() = "nbvkit compiled core (private; use the nbvkit package)";
  nbv::bind::init_common(m);
  nbv::bind::init_mesh(m);
  nbv::bind::init_sensors(m);
  nbv::bind::init_map(m);
  nbv::bind::init_cloud(m);
  nbv::bind::init_evaluation(m);
  nbv::bind::init_views(m);
  nbv::bind::init_symmetry(m);
  nbv::bind::init_planning(m);
  nbv::bind::init_observability(m);
}
