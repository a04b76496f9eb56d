#include "nbv/raycast.hpp"
#include "nbv/parallel.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <string>

namespace nbv {
namespace {

void device_error(void*, RTCError code, const char* str) {
  // Errors are checked after each call through rtcGetDeviceError; nothing to do here.
  (void)code;
  (void)str;
}

void check(RTCDevice device, const char* what) {
  const RTCError err = rtcGetDeviceError(device);
  if (err != RTC_ERROR_NONE)
    throw std::runtime_error(std::string("Embree error in ") + what + ": code " +
                             std::to_string(static_cast<int>(err)));
}

}  // namespace

RaycastScene::RaycastScene(const Mesh& mesh, const RaycastOptions& options) : mesh_(mesh) {
  mesh_.validate();
  if (mesh_.vertices.cwiseAbs().maxCoeff() > kMaxCoordinate)
    throw std::invalid_argument("mesh vertices reach " + fmt(mesh_.vertices.cwiseAbs().maxCoeff()) +
                                " m, beyond the +-1e9 m the ray caster can represent");
  if (mesh_.vertices.rows() && mesh_.vertices.cwiseAbs().maxCoeff() > kLocalExtent)
    origin_ =
        0.5 *
        (mesh_.vertices.colwise().minCoeff() + mesh_.vertices.colwise().maxCoeff()).transpose();
  device_ = rtcNewDevice(nullptr);
  if (!device_) throw std::runtime_error("Embree: cannot create a device");
  rtcSetDeviceErrorFunction(device_, device_error, nullptr);
  scene_ = rtcNewScene(device_);
  rtcSetSceneBuildQuality(
      scene_, options.high_quality_bvh ? RTC_BUILD_QUALITY_HIGH : RTC_BUILD_QUALITY_MEDIUM);
  rtcSetSceneFlags(scene_, RTC_SCENE_FLAG_ROBUST);
  RTCGeometry geom = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_TRIANGLE);
  const auto nv = static_cast<std::size_t>(mesh_.vertices.rows());
  const auto nf = static_cast<std::size_t>(mesh_.faces.rows());
  auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0,
                                                        RTC_FORMAT_FLOAT3, 3 * sizeof(float), nv));
  auto* f = static_cast<unsigned*>(rtcSetNewGeometryBuffer(
      geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), nf));
  check(device_, "rtcSetNewGeometryBuffer");
  for (std::size_t i = 0; i < nv; ++i)
    for (int k = 0; k < 3; ++k)
      v[3 * i + k] = static_cast<float>(mesh_.vertices(i, k) - origin_[k]);
  for (std::size_t i = 0; i < nf; ++i)
    for (int k = 0; k < 3; ++k) f[3 * i + k] = static_cast<unsigned>(mesh_.faces(i, k));
  rtcSetGeometryMask(geom, 0xFFFFFFFFu);
  rtcCommitGeometry(geom);
  rtcAttachGeometry(scene_, geom);
  rtcReleaseGeometry(geom);
  core_arena()->execute([&] { rtcCommitScene(scene_); });
  check(device_, "rtcCommitScene");
}

RaycastScene::~RaycastScene() {
  if (scene_) rtcReleaseScene(scene_);
  if (device_) rtcReleaseDevice(device_);
}

double RaycastScene::refine(const Eigen::Vector3d& o, const Eigen::Vector3d& d, int prim,
                            double t_float) const {
  const Eigen::Vector3d a = mesh_.vertices.row(mesh_.faces(prim, 0));
  const Eigen::Vector3d b = mesh_.vertices.row(mesh_.faces(prim, 1));
  const Eigen::Vector3d c = mesh_.vertices.row(mesh_.faces(prim, 2));
  const Eigen::Vector3d n = (b - a).cross(c - a);
  const double den = n.dot(d);
  if (std::abs(den) < 1e-300) return t_float;
  const double t = n.dot(a - o) / den;
  // Guard against a degenerate plane: keep Embree's value if the refinement moved far.
  return (std::isfinite(t) && std::abs(t - t_float) <= 1e-3 * (1.0 + std::abs(t_float))) ? t
                                                                                         : t_float;
}

void RaycastScene::intersect(const PointsRef& origins, const PointsRef& directions, double t_near,
                             double t_far, Eigen::VectorXd& t, Eigen::VectorXi& prim) const {
  const Eigen::Index n = directions.rows();
  if (origins.rows() != 1 && origins.rows() != n)
    throw std::invalid_argument("origins must be (1, 3) or (N, 3) with N = number of directions");
  if (!(t_near >= 0) || !(t_far > t_near))
    throw std::invalid_argument("ray interval must satisfy 0 <= t_near < t_far");
  require_finite(origins, "ray origins");
  for (Eigen::Index i = 0; i < origins.rows(); ++i)
    require_representable(origins.row(i).transpose(), "ray origin " + std::to_string(i));
  // Embree takes a ray only with every component of its direction within about 1.8e18 in single
  // precision (and aborts the process otherwise); one pass, false for NaN too
  if (!(directions.array().abs() <= kMaxDirection).all()) {
    require_finite(directions, "ray directions");
    Eigen::Index i = 0;
    while (directions.row(i).cwiseAbs().maxCoeff() <= kMaxDirection) ++i;
    std::ostringstream s;
    s.precision(6);
    s << "ray direction " << i << " (" << directions(i, 0) << ", " << directions(i, 1) << ", "
      << directions(i, 2) << ") is too long: components must be within +-" << kMaxDirection
      << " (a unit vector gives t in metres)";
    throw std::invalid_argument(s.str());
  }
  t.setConstant(n, std::numeric_limits<double>::infinity());
  prim.setConstant(n, -1);
  const bool shared = origins.rows() == 1;
  const float tf =
      std::isfinite(t_far) ? static_cast<float>(t_far) : std::numeric_limits<float>::infinity();
  parallel_chunks(static_cast<std::size_t>(n), 256, [&](std::size_t b, std::size_t e) {
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    for (std::size_t i = b; i < e; ++i) {
      const Eigen::Vector3d o = origins.row(shared ? 0 : static_cast<Eigen::Index>(i));
      const Eigen::Vector3d d = directions.row(static_cast<Eigen::Index>(i));
      RTCRayHit rh;
      rh.ray.org_x = static_cast<float>(o.x() - origin_.x());
      rh.ray.org_y = static_cast<float>(o.y() - origin_.y());
      rh.ray.org_z = static_cast<float>(o.z() - origin_.z());
      rh.ray.dir_x = static_cast<float>(d.x());
      rh.ray.dir_y = static_cast<float>(d.y());
      rh.ray.dir_z = static_cast<float>(d.z());
      rh.ray.tnear = static_cast<float>(t_near);
      rh.ray.tfar = tf;
      rh.ray.time = 0;
      rh.ray.mask = 0xFFFFFFFFu;
      rh.ray.id = 0;
      rh.ray.flags = 0;
      rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
      rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
      rtcIntersect1(scene_, &ctx, &rh);
      if (rh.hit.geomID != RTC_INVALID_GEOMETRY_ID) {
        const double tr = refine(o, d, static_cast<int>(rh.hit.primID), rh.ray.tfar);
        if (tr >= t_near * (1.0 - 1e-9) && tr <= t_far * (1.0 + 1e-9)) {
          t[static_cast<Eigen::Index>(i)] = tr;
          prim[static_cast<Eigen::Index>(i)] = static_cast<int>(rh.hit.primID);
        }
      }
    }
  });
}

void RaycastScene::intersect_coherent(const Eigen::Vector3d& o, const Eigen::Matrix3d& R,
                                      const Points& dirs_sensor, const Eigen::VectorXd& t_far,
                                      Eigen::VectorXd& t, bool parallel) const {
  const Eigen::Index n = dirs_sensor.rows();
  t.resize(n);  // every ray's entry is written below, once
  const std::size_t packets = static_cast<std::size_t>((n + 15) / 16);
  const Eigen::Matrix3f Rf = R.cast<float>();
  const float ox = static_cast<float>(o.x() - origin_.x()),
              oy = static_cast<float>(o.y() - origin_.y()),
              oz = static_cast<float>(o.z() - origin_.z());
  const double* dirs = dirs_sensor.data();  // row-major: ray i's direction at 3 i
  auto body = [&](std::size_t pb, std::size_t pe) {
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    alignas(64) int valid[16];
    alignas(64) RTCRayHit16 rh;
    // what no ray of a packet changes: set once
    for (int k = 0; k < 16; ++k) {
      rh.ray.org_x[k] = ox;
      rh.ray.org_y[k] = oy;
      rh.ray.org_z[k] = oz;
      rh.ray.tnear[k] = 0.0f;
      rh.ray.time[k] = 0.0f;
      rh.ray.mask[k] = 0xFFFFFFFFu;
      rh.ray.id[k] = static_cast<unsigned>(k);
      rh.ray.flags[k] = 0;
    }
    for (std::size_t p = pb; p < pe; ++p) {
      const Eigen::Index base = static_cast<Eigen::Index>(p * 16);
      const int lanes = static_cast<int>(std::min<Eigen::Index>(16, n - base));
      for (int k = 0; k < 16; ++k) {
        const Eigen::Index j = k < lanes ? base + k : n - 1;
        valid[k] = k < lanes ? -1 : 0;
        const double* s = dirs + 3 * j;
        const Eigen::Vector3f d =
            Rf * Eigen::Vector3f(static_cast<float>(s[0]), static_cast<float>(s[1]),
                                 static_cast<float>(s[2]));
        rh.ray.dir_x[k] = d.x();
        rh.ray.dir_y[k] = d.y();
        rh.ray.dir_z[k] = d.z();
        // A hair beyond t_far so that a hit exactly at the limit survives float rounding; the
        // double-refined distance is checked against t_far below.
        rh.ray.tfar[k] = static_cast<float>(t_far[j]) * (1.0f + 1e-5f);
        rh.hit.geomID[k] = RTC_INVALID_GEOMETRY_ID;
        rh.hit.instID[0][k] = RTC_INVALID_GEOMETRY_ID;
      }
      rtcIntersect16(valid, scene_, &ctx, &rh);
      for (int k = 0; k < lanes; ++k) {
        const Eigen::Index i = base + k;
        double ti = std::numeric_limits<double>::infinity();
        if (rh.hit.geomID[k] != RTC_INVALID_GEOMETRY_ID) {
          const Eigen::Vector3d d = R * dirs_sensor.row(i).transpose();
          const double tr = refine(o, d, static_cast<int>(rh.hit.primID[k]), rh.ray.tfar[k]);
          if (tr >= 0 && tr <= t_far[i] * (1.0 + 1e-9)) ti = tr;  // a hit at the limit is in range
        }
        t[i] = ti;
      }
    }
  };
  if (parallel)
    parallel_chunks(packets, 16, body);
  else
    body(0, packets);
}

}  // namespace nbv
