#include "nbv/sensors.hpp"
#include "bindings.hpp"
#include "nbv/observability.hpp"
#include "nbv/parallel.hpp"
#include "options.hpp"

namespace nbv::bind {
namespace {

std::shared_ptr<const RaycastScene> scene_of(const py::handle& obj) {
  if (py::isinstance<RaycastScene>(obj)) return obj.cast<std::shared_ptr<RaycastScene>>();
  if (py::isinstance<Mesh>(obj))
    return std::make_shared<RaycastScene>(*obj.cast<std::shared_ptr<Mesh>>());
  throw py::type_error("expected an nbvkit.Mesh or nbvkit.RaycastScene");
}

template <typename Sensor>
Scan scan_transform(const Sensor& s, const py::handle& T) {
  const Eigen::Isometry3d Tws = transform_arg(T, "T_world_sensor");
  py::gil_scoped_release release;
  return s.scan(Tws);
}

template <typename Sensor>
Scan scan_pose(const Sensor& s, const py::handle& pose) {
  const Pose p = pose_arg(pose, "vehicle pose");
  py::gil_scoped_release release;
  return s.scan_pose(p);
}

}  // namespace

void init_sensors(py::module_& m) {
  {
    OptionsClass<RaycastOptions> binder(m, "RaycastOptions", "Options of RaycastScene.");
    using S = RaycastOptions;
    NBV_RAYCAST_OPTIONS(NBV_BIND_FIELD)
    binder.finish();
  }
  py::class_<RaycastScene, std::shared_ptr<RaycastScene>>(m, "RaycastScene", R"doc(
Embree ray-casting scene over a mesh (build once, share between sensors); `options`
(RaycastOptions, a dict or None) with keyword overrides, e.g. high_quality_bvh=True.)doc")
      .def(py::init([](const Mesh& mesh, const py::object& options, const py::kwargs& kw) {
             const auto o = options_with_keywords<RaycastOptions>(options, kw);
             py::gil_scoped_release release;
             return std::make_shared<RaycastScene>(mesh, o);
           }),
           py::arg("mesh"), py::arg("options") = py::none())
      .def_property_readonly("mesh", [](const RaycastScene& s) { return s.mesh(); })
      .def(
          "intersect",
          [](const RaycastScene& s, const py::handle& origins, const py::handle& dirs,
             double t_near, double t_far) {
            auto o = points_arg(origins, "ray origins");
            auto d = points_arg(dirs, "ray directions");
            Eigen::VectorXd t;
            Eigen::VectorXi prim;
            {
              py::gil_scoped_release release;
              s.intersect(o.map(), d.map(), t_near, t_far, t, prim);
            }
            return py::make_tuple(t, prim);
          },
          py::arg("origins"), py::arg("directions"), py::arg("t_near") = 0.0,
          py::arg("t_far") = std::numeric_limits<double>::infinity(),
          "Cast rays o + t d. origins (1, 3) or (N, 3), directions (N, 3) float64 (unit for t in "
          "metres).\n"
          "Returns (t (N,) float64, inf = no hit in [t_near, t_far]; triangle (N,) int32, -1 = no "
          "hit).")
      .def(
          "within",
          [](const RaycastScene& s, const py::handle& points, double radius) {
            check_radius(radius);
            auto p = points_arg(points, "points");
            py::array_t<bool> out(static_cast<py::ssize_t>(p.map().rows()));
            bool* o = out.mutable_data();
            {
              py::gil_scoped_release release;
              for (Eigen::Index i = 0; i < p.map().rows(); ++i)
                o[i] = mesh_within(s, p.map().row(i).transpose(), radius);
            }
            return out;
          },
          py::arg("points"), py::arg("radius"),
          "(N,) bool per point (N, 3): some triangle of the mesh lies within `radius` (m) of it "
          "(an Embree point query: a proximity sensor of that range).")
      .def(
          "distances",
          [](const RaycastScene& s, const py::handle& points, double max_distance) {
            if (!(max_distance >= 0))  // (NaN too; infinity: every point's nearest triangle)
              throw py::value_error("max_distance must be >= 0 m (or infinity), got " +
                                    fmt(max_distance));
            auto p = points_arg(points, "points");
            const auto P = p.map();
            py::array_t<double> out(static_cast<py::ssize_t>(P.rows()));
            double* o = out.mutable_data();
            {
              py::gil_scoped_release release;
              parallel_chunks(std::size_t(P.rows()), 256, [&](std::size_t b, std::size_t e) {
                for (std::size_t i = b; i < e; ++i)
                  o[i] = mesh_distance(s, P.row(Eigen::Index(i)).transpose(), max_distance);
              });
            }
            return out;
          },
          py::arg("points"), py::arg("max_distance") = std::numeric_limits<double>::infinity(),
          "(N,) float64 per point (N, 3): the distance (m) to the mesh's nearest triangle, inf "
          "where none lies within max_distance (an Embree point query).");

  py::class_<Scan>(m, "Scan", R"doc(
One sensor reading, world frame. origin (3,); hits (N, 3) surface points within range; free_ends
(M, 3) ends at max range of rays that hit nothing within range (to clear free space); hit_rays (N,)
and free_rays (M,) the ray index of each hit and free end (camera: v * width + u); depth: camera
(H, W) depth along the optical axis, laser (1, R) range along each beam, inf where there is no
valid return.)doc")
      .def_readonly("origin", &Scan::origin)
      .def_readonly("hits", &Scan::hits)
      .def_readonly("free_ends", &Scan::free_ends)
      .def_readonly("hit_rays", &Scan::hit_rays)
      .def_readonly("free_rays", &Scan::free_rays)
      .def_readonly("sparse_hits", &Scan::sparse_hits,
                    "the leading hits a coarse frame kept (refine_frame; 0 for a scan as cast): "
                    "the camera observations' saturation does not count them")
      .def_readonly("depth", &Scan::depth)
      .def("__repr__", [](const Scan& s) {
        return "<nbvkit.Scan " + std::to_string(s.hits.rows()) + " hits, " +
               std::to_string(s.free_ends.rows()) + " free rays>";
      });

  {
    OptionsClass<DepthCameraOptions> binder(
        m, "DepthCameraOptions",
        "Options of the RGB-D camera (paper Table 1); keyword constructor, checked (ValueError "
        "naming the bad value); each field is documented in DepthCameraOptions.fields().");
    using S = DepthCameraOptions;
    NBV_DEPTH_CAMERA_OPTIONS(NBV_BIND_FIELD)
    binder.finish();
  }

  py::class_<DepthCamera, std::shared_ptr<DepthCamera>>(m, "DepthCamera", R"doc(
Pinhole RGB-D (depth) camera ray-cast against a mesh with Embree (16-ray packets over 4x4 tiles).

scene: an nbvkit.Mesh or nbvkit.RaycastScene; options: DepthCameraOptions (or a dict, or None for
the defaults) with keyword overrides: width, height, hfov_deg, vfov_deg, min_range, max_range,
noise_k, seed, mount. Ranges are depths along the optical axis (metres).
noise_k: depth noise sigma = noise_k * z^2 (0 = exact; the authors used 0.0025), seeded.
mount: 4x4 T_body_sensor (default identity: at the body origin, no tilt).
The sensor looks along its +x (y left, z up); pixel (u, v) looks along
(1, -(u + 0.5 - W/2)/fx, -(v + 0.5 - H/2)/fy).)doc")
      .def(py::init([](const py::handle& scene, const py::object& options, const py::kwargs& kw) {
             const auto o = options_with_keywords<DepthCameraOptions>(options, kw);
             return std::make_shared<DepthCamera>(scene_of(scene), o);
           }),
           py::arg("scene"), py::arg("options") = py::none())
      .def_property_readonly("width", [](const DepthCamera& c) { return c.options().width; })
      .def_property_readonly("height", [](const DepthCamera& c) { return c.options().height; })
      .def_property_readonly("hfov_deg", [](const DepthCamera& c) { return c.options().hfov_deg; })
      .def_property_readonly("vfov_deg", [](const DepthCamera& c) { return c.options().vfov_deg; })
      .def_property_readonly("min_range",
                             [](const DepthCamera& c) { return c.options().min_range; })
      .def_property_readonly("max_range",
                             [](const DepthCamera& c) { return c.options().max_range; })
      .def_property_readonly("noise_k", [](const DepthCamera& c) { return c.options().noise_k; })
      .def_property_readonly(
          "mount", [](const DepthCamera& c) { return c.options().mount.matrix(); },
          "4x4 T_body_sensor")
      .def_property_readonly("fx", &DepthCamera::fx)
      .def_property_readonly("fy", &DepthCamera::fy)
      .def_property_readonly("directions", &DepthCamera::directions,
                             "(H*W, 3) unit ray directions in the sensor frame, row v*W + u")
      .def("frustum_volume", &DepthCamera::frustum_volume,
           "Volume (m^3) of the view frustum between the near and far depth planes.")
      .def("scan", &scan_transform<DepthCamera>, py::arg("T_world_sensor"),
           "Scan from a 4x4 sensor pose T_world_sensor. Returns an nbvkit.Scan.")
      .def("scan_pose", &scan_pose<DepthCamera>, py::arg("pose"),
           "Scan from a view (x, y, z, yaw) or (x, y, z, yaw, pitch): the camera rides a gimbal\n"
           "that pitches it (radians, > 0 looks down, |pitch| <= pi/2) before its mount:\n"
           "T_world_sensor = T(x, y, z) Rz(yaw) Ry(pitch) mount (gimbal_transform). 4 numbers\n"
           "mean pitch 0, the level camera.")
      .def(
          "scan_pixels",
          [](const DepthCamera& c, const py::handle& T, const py::handle& pixels) {
            const Eigen::Isometry3d Tws = transform_arg(T, "T_world_sensor");
            const py::array a = py::array::ensure(pixels);
            if (!a || a.ndim() != 1 ||
                (a.size() && a.dtype().kind() != 'i' && a.dtype().kind() != 'u'))
              throw py::value_error("camera pixels must be a 1-D array of integer indices");
            const auto p = py::array_t<std::int64_t, py::array::forcecast>::ensure(a);
            Eigen::VectorXi px(p.size());
            for (py::ssize_t i = 0; i < p.size(); ++i) {
              const std::int64_t v = p.at(i);
              if (v < 0 || v >= std::int64_t(c.directions().rows()))
                throw py::value_error("camera pixel " + std::to_string(v) + " is outside the " +
                                      std::to_string(c.options().width) + " x " +
                                      std::to_string(c.options().height) + " image");
              px[i] = int(v);
            }
            py::gil_scoped_release release;
            return c.scan_pixels(Tws, px);
          },
          py::arg("T_world_sensor"), py::arg("pixels"),
          "Scan of only the listed pixels (v * width + u) from a 4x4 sensor pose, as scan casts\n"
          "them (the next frame of noise): hits and free ends in the pixels' order, hit_rays and\n"
          "free_rays the pixel of each, depth (1, K) each listed pixel's. ValueError for a pixel "
          "outside\n"
          "the image.")
      .def(
          "reset_noise",
          [](DepthCamera& c, const py::object& seed) { c.reset_noise(seed_arg(seed)); },
          py::arg("seed"));

  {
    OptionsClass<LaserScannerOptions> binder(
        m, "LaserScannerOptions",
        "Options of the laser scanner (paper Table 1); keyword constructor, checked (ValueError "
        "naming the bad value); each field is documented in LaserScannerOptions.fields().");
    using S = LaserScannerOptions;
    NBV_LASER_SCANNER_OPTIONS(NBV_BIND_FIELD)
    binder.finish().def_property_readonly("num_beams", &LaserScannerOptions::num_beams);
  }

  py::class_<LaserScanner, std::shared_ptr<LaserScanner>>(m, "LaserScanner", R"doc(
Single-layer 2D laser scanner ray-cast against a mesh with Embree.

Beams lie in the sensor's x-y plane from -fov/2 to +fov/2 (counter-clockwise from +x), one per
resolution_deg (180 deg / 0.25 deg -> 721 beams). Ranges along the beam, metres.
mount: 4x4 T_body_sensor (default: body origin, pitched 10 deg down as in Table 1).
options: LaserScannerOptions (or a dict, or None for the defaults) with keyword overrides: fov_deg,
resolution_deg, min_range, max_range, noise_sigma, seed, mount.)doc")
      .def(py::init([](const py::handle& scene, const py::object& options, const py::kwargs& kw) {
             const auto o = options_with_keywords<LaserScannerOptions>(options, kw);
             return std::make_shared<LaserScanner>(scene_of(scene), o);
           }),
           py::arg("scene"), py::arg("options") = py::none())
      .def_property_readonly("num_beams",
                             [](const LaserScanner& l) { return l.options().num_beams(); })
      .def_property_readonly("fov_deg", [](const LaserScanner& l) { return l.options().fov_deg; })
      .def_property_readonly("resolution_deg",
                             [](const LaserScanner& l) { return l.options().resolution_deg; })
      .def_property_readonly("min_range",
                             [](const LaserScanner& l) { return l.options().min_range; })
      .def_property_readonly("max_range",
                             [](const LaserScanner& l) { return l.options().max_range; })
      .def_property_readonly(
          "mount", [](const LaserScanner& l) { return l.options().mount.matrix(); },
          "4x4 T_body_sensor")
      .def_property_readonly("angles", &LaserScanner::angles, "(R,) beam angles, radians")
      .def_property_readonly("directions", &LaserScanner::directions,
                             "(R, 3) unit beam directions, sensor frame")
      .def("scan", &scan_transform<LaserScanner>, py::arg("T_world_sensor"))
      .def("scan_pose", &scan_pose<LaserScanner>, py::arg("pose"),
           "Scan from a vehicle pose (x, y, z, yaw) through the laser's fixed mount on the body.\n"
           "A 5th number (the camera gimbal's pitch) is accepted and ignored: the laser does not\n"
           "ride the gimbal.")
      .def(
          "reset_noise",
          [](LaserScanner& l, const py::object& seed) { l.reset_noise(seed_arg(seed)); },
          py::arg("seed"));
}

}  // namespace nbv::bind
