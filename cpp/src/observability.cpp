#include "nbv/observability.hpp"
#include "nbv/parallel.hpp"

#include <embree3/rtcore.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <deque>
#include <limits>
#include <sstream>

namespace nbv {
namespace {

// Closest point on triangle abc to p (Ericson, Real-Time Collision Detection, 5.1.5).
Eigen::Vector3d closest_on_triangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                    const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + ab * (d1 / (d1 - d3));
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + ac * (d2 / (d2 - d6));
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0)
    return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
  const double den = 1.0 / (va + vb + vc);
  return a + ab * (vb * den) + ac * (vc * den);
}

struct WithinQuery {
  const Mesh* mesh;
  Eigen::Vector3d p;
  double r2;
  bool found = false;
};

bool within_callback(RTCPointQueryFunctionArguments* args) {
  auto* q = static_cast<WithinQuery*>(args->userPtr);
  if (q->found) return false;
  const Mesh& m = *q->mesh;
  const auto f = static_cast<Eigen::Index>(args->primID);
  const Eigen::Vector3d a = m.vertices.row(m.faces(f, 0));
  const Eigen::Vector3d b = m.vertices.row(m.faces(f, 1));
  const Eigen::Vector3d c = m.vertices.row(m.faces(f, 2));
  if ((closest_on_triangle(q->p, a, b, c) - q->p).squaredNorm() <= q->r2) {
    q->found = true;
    args->query->radius = 0.0f;  // ends the traversal
    return true;
  }
  return false;
}

// True if the segment from o along unit d over (t_near, t_far) hits the mesh.
bool occluded(const RaycastScene& scene, const Eigen::Vector3d& o, const Eigen::Vector3d& d,
              double t_near, double t_far) {
  if (!(t_far > t_near)) return false;
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  RTCRay ray;
  const Eigen::Vector3d local = o - scene.origin();  // Embree's coordinates
  ray.org_x = static_cast<float>(local.x());
  ray.org_y = static_cast<float>(local.y());
  ray.org_z = static_cast<float>(local.z());
  ray.dir_x = static_cast<float>(d.x());
  ray.dir_y = static_cast<float>(d.y());
  ray.dir_z = static_cast<float>(d.z());
  ray.tnear = static_cast<float>(t_near);
  ray.tfar = static_cast<float>(t_far);
  ray.time = 0.0f;
  ray.mask = 0xFFFFFFFFu;
  ray.id = 0;
  ray.flags = 0;
  rtcOccluded1(scene.handle(), &ctx, &ray);
  return ray.tfar < 0.0f;  // -inf when something was hit
}

struct NearestQuery {
  const Mesh* mesh;
  Eigen::Vector3d p;
  double d2;  // the least squared distance found so far (the query's radius squared at first)
  bool found = false;
};

bool nearest_callback(RTCPointQueryFunctionArguments* args) {
  auto* q = static_cast<NearestQuery*>(args->userPtr);
  const Mesh& m = *q->mesh;
  const auto f = static_cast<Eigen::Index>(args->primID);
  const Eigen::Vector3d a = m.vertices.row(m.faces(f, 0));
  const Eigen::Vector3d b = m.vertices.row(m.faces(f, 1));
  const Eigen::Vector3d c = m.vertices.row(m.faces(f, 2));
  const double d2 = (closest_on_triangle(q->p, a, b, c) - q->p).squaredNorm();
  if (d2 > q->d2) return false;
  q->d2 = d2;
  q->found = true;
  // the search goes on only where a nearer triangle may lie (a little beyond: float32 bounds)
  args->query->radius = static_cast<float>(std::sqrt(d2)) * 1.0001f + 1e-6f;
  return true;
}

// An Embree point query round p (world coordinates) of `radius` m (a little beyond: float32
// bounds; one past a float's range, infinity, is every triangle until the callback shrinks it;
// converted without overflow), calling `callback` with `user`.
void point_query(const RaycastScene& scene, const Eigen::Vector3d& p, double radius,
                 RTCPointQueryFunction callback, void* user) {
  RTCPointQuery pq;
  const Eigen::Vector3d local = p - scene.origin();  // Embree's coordinates
  pq.x = static_cast<float>(local.x());
  pq.y = static_cast<float>(local.y());
  pq.z = static_cast<float>(local.z());
  pq.time = 0.0f;
  const double most = std::numeric_limits<float>::max();  // (times 1.0001f: infinity)
  pq.radius = static_cast<float>(std::min(radius, most)) * 1.0001f + 1e-6f;
  RTCPointQueryContext ctx;
  rtcInitPointQueryContext(&ctx);
  rtcPointQuery(scene.handle(), &pq, &ctx, callback, user);
}

// m: occlusion rays start and end this far from their ends (float precision of the BVH is ~4e-6 m
// at 40 m from the origin); a sample closer than this to an edge may see past the edge
constexpr double kSurfaceEps = 5e-4;

}  // namespace

void ObservabilityOptions::validate() const {
  if (!(std::isfinite(pose_spacing) && pose_spacing > 0))
    throw std::invalid_argument("pose_spacing must be a positive number of metres, got " +
                                fmt(pose_spacing));
  if (!(std::isfinite(collision_radius) && collision_radius >= 0))
    throw std::invalid_argument("collision_radius must be >= 0 m, got " + fmt(collision_radius));
  if (!(max_incidence_deg > 0 && max_incidence_deg <= 90))
    throw std::invalid_argument("max_incidence_deg must be in (0, 90], got " +
                                fmt(max_incidence_deg));
  if (yaw_steps < 0 || yaw_steps > 1000)
    throw std::invalid_argument("yaw_steps must be in [0, 1000], got " + std::to_string(yaw_steps));
  if (!(gimbal_min_deg >= -90.0 && gimbal_max_deg <= 90.0 && gimbal_min_deg <= gimbal_max_deg))
    throw std::invalid_argument(
        "gimbal_min_deg <= gimbal_max_deg within [-90, 90] required, got [" +
        std::to_string(gimbal_min_deg) + ", " + std::to_string(gimbal_max_deg) + "]");
}

double mesh_distance(const RaycastScene& scene, const Eigen::Vector3d& p, double max_distance) {
  NearestQuery q{&scene.mesh(), p, max_distance * max_distance};  // (infinity stays infinite)
  point_query(scene, p, max_distance, nearest_callback, &q);
  return q.found ? std::sqrt(q.d2) : std::numeric_limits<double>::infinity();
}

bool mesh_within(const RaycastScene& scene, const Eigen::Vector3d& p, double radius) {
  WithinQuery q{&scene.mesh(), p, radius * radius};
  point_query(scene, p, radius, within_callback, &q);
  return q.found;
}

ObservabilityResult observable_samples(const RaycastScene& scene, const PointsRef& points,
                                       const PointsRef& normals, const DepthCameraOptions& camera,
                                       const Eigen::Vector3d& nav_min,
                                       const Eigen::Vector3d& nav_max,
                                       const ObservabilityOptions& options) {
  using clock = std::chrono::steady_clock;
  options.validate();
  camera.validate();
  require_finite(points, "points");
  require_finite(normals, "normals");
  if (normals.rows() != points.rows())
    throw std::invalid_argument("normals must have one row per point (" +
                                std::to_string(points.rows()) + "), got " +
                                std::to_string(normals.rows()));
  if (!nav_min.allFinite() || !nav_max.allFinite() || (nav_max.array() < nav_min.array()).any())
    throw std::invalid_argument("the navigation box needs finite nav_min <= nav_max");
  require_representable(nav_min, "nav_min");  // positions the ray caster can take
  require_representable(nav_max, "nav_max");

  ObservabilityResult res;
  const auto n = static_cast<std::size_t>(points.rows());
  res.observable.assign(n, 0);
  const double s = options.pose_spacing;

  // ---- the lattice of candidate positions: each axis of the box split evenly into the fewest
  // steps of at most the spacing, both faces included (a lattice about the centre left up to a
  // spacing of the box unflown at each face: the air just above a roof, the band under a wing);
  // an axis shorter than half the spacing holds one level, at its middle
  std::array<double, 3> step{};  // the spacing along each axis, from half the spacing up to it
  std::array<std::int64_t, 3> dim{};
  Eigen::Vector3d origin;
  double lattice = 1.0;  // counted in floating point first: no integer overflows
  for (int a = 0; a < 3; ++a) {
    const double extent = nav_max[a] - nav_min[a];
    const double steps = extent < 0.5 * s ? 0.0 : std::ceil(extent / s - 1e-9);
    step[a] = steps > 0.0 ? extent / steps : s;
    origin[a] = steps > 0.0 ? nav_min[a] : 0.5 * (nav_min[a] + nav_max[a]);
    lattice *= steps + 1.0;
    dim[a] = static_cast<std::int64_t>(std::min(steps, 2e8)) + 1;
  }
  if (!(lattice <= 2e8))
    throw std::invalid_argument("pose_spacing " + fmt(s) + " m gives " + fmt(lattice) +
                                " candidate positions (at most 2e8): use a coarser spacing");
  const std::int64_t total = dim[0] * dim[1] * dim[2];
  res.lattice_points = total;
  auto flat = [&](std::int64_t i, std::int64_t j, std::int64_t k) {
    return (k * dim[1] + j) * dim[0] + i;
  };
  // a level along an axis (the last one exactly on the face), computed where used: a table of
  // levels would cost 8 bytes each, 1.6 GB on a one-axis lattice of 2e8
  auto level = [&](int a, std::int64_t l) {
    return dim[a] > 1 && l == dim[a] - 1 ? nav_max[a]
                                         : origin[a] + static_cast<double>(l) * step[a];
  };
  auto pos = [&](std::int64_t i, std::int64_t j, std::int64_t k) {
    return Eigen::Vector3d(level(0, i), level(1, j), level(2, k));
  };

  auto t0 = clock::now();
  std::vector<std::uint8_t> free(static_cast<std::size_t>(total), 0);
  // bit a set: the edge to the +a neighbour does not cross the mesh
  std::vector<std::uint8_t> edges(static_cast<std::size_t>(total), 0);
  parallel_chunks(static_cast<std::size_t>(total), 256, [&](std::size_t b, std::size_t e) {
    for (std::size_t f = b; f < e; ++f) {
      const auto fi = static_cast<std::int64_t>(f);
      const std::int64_t i = fi % dim[0], j = (fi / dim[0]) % dim[1], k = fi / (dim[0] * dim[1]);
      free[f] = !mesh_within(scene, pos(i, j, k), options.collision_radius);
    }
  });
  // an edge is flown along: the mesh does not cross it, and the vehicle's sphere fits at points
  // along it at most half a radius apart (their union holds a capsule of 0.97 x the radius), so
  // an opening narrower than the vehicle does not connect the positions either side of it
  const double r = options.collision_radius;
  std::array<int, 3> checks{};  // points checked along an edge of each axis
  for (int a = 0; a < 3; ++a)
    checks[a] = r > 0.0 ? static_cast<int>(std::ceil(step[a] / (0.5 * r) - 1e-9)) : 1;
  parallel_chunks(static_cast<std::size_t>(total), 256, [&](std::size_t b, std::size_t e) {
    for (std::size_t f = b; f < e; ++f) {
      if (!free[f]) continue;
      const auto fi = static_cast<std::int64_t>(f);
      const std::int64_t i = fi % dim[0], j = (fi / dim[0]) % dim[1], k = fi / (dim[0] * dim[1]);
      const std::array<std::int64_t, 3> ijk{i, j, k};
      const Eigen::Vector3d p = pos(i, j, k);
      std::uint8_t bits = 0;
      for (int a = 0; a < 3; ++a) {
        if (ijk[a] + 1 >= dim[a]) continue;
        std::array<std::int64_t, 3> q = ijk;
        ++q[a];
        if (!free[static_cast<std::size_t>(flat(q[0], q[1], q[2]))]) continue;
        const Eigen::Vector3d d = Eigen::Vector3d::Unit(a);
        if (occluded(scene, p, d, 0.0, step[a])) continue;
        bool fits = true;
        for (int t = 1; t < checks[a] && fits; ++t)
          fits = !mesh_within(scene, p + d * (step[a] * t / checks[a]), r);
        if (fits) bits |= std::uint8_t(1u << a);
      }
      edges[f] = bits;
    }
  });
  res.timings_s.emplace_back("collision", seconds_since(t0));

  // ---- reachability: flood fill from where the vehicle comes from, outside the structure: the
  // free lattice points on the navigation box's sides and top whose ray out of the box escapes
  // the mesh. With none (a box that hugs the structure), from every free point that sees out
  // along +-x, +-y or +z (not -z: the ground is not in the mesh)
  t0 = clock::now();
  std::vector<std::uint8_t> reach(static_cast<std::size_t>(total), 0);
  const double inf = std::numeric_limits<double>::infinity();
  const Eigen::Vector3d dirs[5] = {-Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitX(),
                                   -Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitY(),
                                   Eigen::Vector3d::UnitZ()};
  auto seed = [&](bool boundary_only) {
    parallel_chunks(static_cast<std::size_t>(total), 256, [&](std::size_t b, std::size_t e) {
      for (std::size_t f = b; f < e; ++f) {
        if (!free[f]) continue;
        const auto fi = static_cast<std::int64_t>(f);
        const std::int64_t i = fi % dim[0], j = (fi / dim[0]) % dim[1], k = fi / (dim[0] * dim[1]);
        // the faces the point lies on, as dirs' order: -x, +x, -y, +y, +z
        const bool on[5] = {i == 0, i == dim[0] - 1, j == 0, j == dim[1] - 1, k == dim[2] - 1};
        const Eigen::Vector3d p = pos(i, j, k);
        for (int w = 0; w < 5; ++w)
          if ((on[w] || !boundary_only) && !occluded(scene, p, dirs[w], 0.0, inf)) {
            reach[f] = 1;
            break;
          }
      }
    });
  };
  seed(true);
  if (std::find(reach.begin(), reach.end(), std::uint8_t(1)) == reach.end()) seed(false);
  std::deque<std::int64_t> queue;
  for (std::int64_t f = 0; f < total; ++f)
    if (reach[static_cast<std::size_t>(f)]) queue.push_back(f);
  const std::array<std::int64_t, 3> stride{1, dim[0], dim[0] * dim[1]};
  while (!queue.empty()) {
    const std::int64_t f = queue.front();
    queue.pop_front();
    const std::array<std::int64_t, 3> ijk{f % dim[0], (f / dim[0]) % dim[1], f / (dim[0] * dim[1])};
    for (int a = 0; a < 3; ++a) {
      // +a neighbour through this point's edge bit; -a neighbour through its own bit
      if (ijk[a] + 1 < dim[a] && (edges[static_cast<std::size_t>(f)] >> a & 1u)) {
        const std::int64_t g = f + stride[a];
        if (!reach[static_cast<std::size_t>(g)]) {
          reach[static_cast<std::size_t>(g)] = 1;
          queue.push_back(g);
        }
      }
      if (ijk[a] > 0) {
        const std::int64_t g = f - stride[a];
        if ((edges[static_cast<std::size_t>(g)] >> a & 1u) && !reach[static_cast<std::size_t>(g)]) {
          reach[static_cast<std::size_t>(g)] = 1;
          queue.push_back(g);
        }
      }
    }
  }
  std::int64_t n_free = 0, n_reach = 0;
  for (std::int64_t f = 0; f < total; ++f) {
    n_free += free[static_cast<std::size_t>(f)];
    n_reach += reach[static_cast<std::size_t>(f)];
  }
  res.colliding = total - n_free;
  res.unreachable = n_free - n_reach;
  res.poses.resize(n_reach, 3);
  {
    Eigen::Index r = 0;
    for (std::int64_t f = 0; f < total; ++f)
      if (reach[static_cast<std::size_t>(f)])
        res.poses.row(r++) = pos(f % dim[0], (f / dim[0]) % dim[1], f / (dim[0] * dim[1]));
  }
  res.timings_s.emplace_back("reachability", seconds_since(t0));

  // ---- the camera: frustum, reach, yaw offsets
  const Eigen::Matrix3d M = camera.mount.linear();
  const Eigen::Matrix3d Mt = M.transpose();
  const double mount_z = camera.mount.translation().z();
  const double th = std::tan(camera.hfov_deg * M_PI / 360.0);
  const double tv = std::tan(camera.vfov_deg * M_PI / 360.0);
  const double diag = std::sqrt(1.0 + th * th + tv * tv);  // corner distance per unit depth
  const double r_max = camera.max_range * diag;
  const Eigen::Vector3d axis = M * Eigen::Vector3d::UnitX();
  const double az0 = std::hypot(axis.x(), axis.y()) > 1e-9 ? std::atan2(axis.y(), axis.x()) : 0.0;
  const double ca = std::cos(az0), sa = std::sin(az0);
  const double half = std::atan(std::sqrt(th * th + tv * tv));
  const int K = options.yaw_steps;
  std::vector<std::pair<double, double>> yaw_cs;  // cos/sin of the offsets, 0 first
  yaw_cs.emplace_back(1.0, 0.0);
  for (int k = 1; k <= K; ++k)
    for (int sgn : {1, -1}) {
      const double a = sgn * half * k / K;
      yaw_cs.emplace_back(std::cos(a), std::sin(a));
    }
  const double cos_inc = std::cos(options.max_incidence_deg * M_PI / 180.0);

  // lattice offsets within r_max (+ the half diagonal of a cell), nearest first
  const double reach_r =
      r_max + 0.5 * std::sqrt(step[0] * step[0] + step[1] * step[1] + step[2] * step[2]);
  std::array<std::int64_t, 3> m{};
  for (int a = 0; a < 3; ++a) m[a] = static_cast<std::int64_t>(std::ceil(reach_r / step[a]));
  std::vector<std::array<std::int32_t, 3>> offsets;
  {
    std::vector<std::pair<double, std::array<std::int32_t, 3>>> tmp;
    for (std::int64_t dk = -m[2]; dk <= m[2]; ++dk)
      for (std::int64_t dj = -m[1]; dj <= m[1]; ++dj)
        for (std::int64_t di = -m[0]; di <= m[0]; ++di) {
          const double x = di * step[0], y = dj * step[1], z = dk * step[2];
          const double d2 = x * x + y * y + z * z;
          if (d2 <= reach_r * reach_r)
            tmp.push_back({d2,
                           {static_cast<std::int32_t>(di), static_cast<std::int32_t>(dj),
                            static_cast<std::int32_t>(dk)}});
        }
    std::sort(tmp.begin(), tmp.end(), [](const auto& x, const auto& y) {
      return x.first < y.first || (x.first == y.first && x.second < y.second);
    });
    offsets.reserve(tmp.size());
    for (const auto& t : tmp) offsets.push_back(t.second);
  }

  // the elevation range the frustum covers (yaw-invariant): a cheap first test
  double el_lo = M_PI, el_hi = -M_PI;
  for (int e = 0; e < 4; ++e)
    for (int k = 0; k <= 256; ++k) {
      const double t = -1.0 + 2.0 * k / 256.0;
      const double u = e < 2 ? t : (e == 2 ? -1.0 : 1.0), w = e < 2 ? (e == 0 ? -1.0 : 1.0) : t;
      const Eigen::Vector3d d = M * Eigen::Vector3d(1.0, u * th, w * tv);
      const double el = std::asin(std::clamp(d.z() / d.norm(), -1.0, 1.0));
      el_lo = std::min(el_lo, el);
      el_hi = std::max(el_hi, el);
    }
  // the gimbal's pitch range (> 0 looks down) widens the band: pitched by p, the frustum's
  // elevations move down by p
  const double g_lo = options.gimbal_min_deg * M_PI / 180.0;
  const double g_hi = options.gimbal_max_deg * M_PI / 180.0;
  const bool gimbal = g_lo != 0.0 || g_hi != 0.0;
  const double axis_el = std::asin(std::clamp(axis.z(), -1.0, 1.0));
  const double cos_ax = std::cos(axis_el), sin_ax = std::sin(axis_el);
  const double cos_g_lo = std::cos(g_lo), sin_g_lo = std::sin(g_lo);
  const double cos_g_hi = std::cos(g_hi), sin_g_hi = std::sin(g_hi);
  // the sample elevations e (|e| <= 90 deg) past which the centring pitch axis_el - e is
  // clamped, as sines: at g_lo from sin_e_hi up, at g_hi from sin_e_lo down (+-2 where that
  // elevation lies past straight up or down: the bound is never or always reached)
  auto sin_of_elevation = [](double e) {
    return e >= M_PI / 2 ? 2.0 : e <= -M_PI / 2 ? -2.0 : std::sin(e);
  };
  const double sin_e_hi = sin_of_elevation(axis_el - g_lo);
  const double sin_e_lo = sin_of_elevation(axis_el - g_hi);
  const double sin_lo = std::sin(std::max(-M_PI / 2, el_lo - g_hi - 1e-3));
  const double sin_hi = std::sin(std::min(M_PI / 2, el_hi - g_lo + 1e-3));

  // ---- the samples, in a spatially coherent order (Morton order of 0.25 m cells)
  t0 = clock::now();
  std::vector<std::pair<std::uint64_t, std::uint32_t>> order(n);
  if (n > 0) {
    const Eigen::Vector3d lo = points.colwise().minCoeff().transpose();
    parallel_chunks(n, 1 << 14, [&](std::size_t b, std::size_t e) {
      for (std::size_t q = b; q < e; ++q) {
        std::uint64_t key = 0;
        for (int a = 0; a < 3; ++a) {
          const auto c = static_cast<std::uint64_t>(
              std::min(2097151.0, (points(static_cast<Eigen::Index>(q), a) - lo[a]) / 0.25));
          for (int bit = 0; bit < 21; ++bit) key |= ((c >> bit) & 1u) << (3 * bit + a);
        }
        order[q] = {key, static_cast<std::uint32_t>(q)};
      }
    });
    std::sort(order.begin(), order.end());
  }
  if (n_reach > 0)
    parallel_chunks(n, 64, [&](std::size_t b, std::size_t e) {
      std::int64_t witness = -1;  // the last sample's seeing position: neighbours share it
      for (std::size_t oq = b; oq < e; ++oq) {
        const std::size_t q = order[oq].second;
        const auto row = static_cast<Eigen::Index>(q);
        const Eigen::Vector3d x = points.row(row).transpose();
        Eigen::Vector3d nrm = normals.row(row).transpose();
        const double nn = nrm.norm();
        const bool has_normal = nn > 1e-12;
        if (has_normal) nrm /= nn;
        // the full test of one lattice position
        auto sees = [&](std::int64_t i, std::int64_t j, std::int64_t k) {
          Eigen::Vector3d c = pos(i, j, k);
          c.z() += mount_z;
          const Eigen::Vector3d v = x - c;  // camera -> sample
          const double dist = v.norm();
          if (dist > r_max || dist < camera.min_range) return false;
          if (v.z() < sin_lo * dist || v.z() > sin_hi * dist) return false;
          if (has_normal && std::abs(nrm.dot(v)) < cos_inc * dist) return false;
          // v turned about z so that its azimuth is the camera axis's (the centring yaw)
          const double vh = std::sqrt(v.x() * v.x() + v.y() * v.y());
          const Eigen::Vector3d u0(vh * ca, vh * sa, v.z());
          // the gimbal's pitch p that centres the sample vertically, within its range: a turn
          // about z keeps the sample's elevation e, so one pitch serves every yaw offset.
          // p = clamp(axis_el - e, g_lo, g_hi), its cosine and sine without a trigonometric
          // call: cos e = vh / dist and sin e = v.z / dist, p clamped where e leaves
          // [axis_el - g_hi, axis_el - g_lo]
          double cp = 1.0, sp = 0.0;
          if (gimbal) {
            const double ce = vh / dist, se = v.z() / dist;
            if (se >= sin_e_hi) {  // e >= axis_el - g_lo: p at g_lo
              cp = cos_g_lo;
              sp = sin_g_lo;
            } else if (se <= sin_e_lo) {  // e <= axis_el - g_hi: p at g_hi
              cp = cos_g_hi;
              sp = sin_g_hi;
            } else {  // p = axis_el - e
              cp = cos_ax * ce + sin_ax * se;
              sp = sin_ax * ce - cos_ax * se;
            }
          }
          bool in_view = false;
          for (const auto& [cy, sy] : yaw_cs) {
            Eigen::Vector3d u(cy * u0.x() - sy * u0.y(), sy * u0.x() + cy * u0.y(), u0.z());
            if (gimbal)  // and pitched by p
              u = Eigen::Vector3d(cp * u.x() - sp * u.z(), u.y(), sp * u.x() + cp * u.z());
            const Eigen::Vector3d cam = Mt * u;  // sensor frame: +x forward, y left, z up
            if (cam.x() < camera.min_range || cam.x() > camera.max_range) continue;
            if (std::abs(cam.y()) > cam.x() * th || std::abs(cam.z()) > cam.x() * tv) continue;
            in_view = true;
            break;
          }
          if (!in_view) return false;
          const Eigen::Vector3d dir = -v / dist;  // sample -> camera
          return !occluded(scene, x, dir, kSurfaceEps, dist - kSurfaceEps);
        };
        if (witness >= 0 &&
            sees(witness % dim[0], (witness / dim[0]) % dim[1], witness / (dim[0] * dim[1]))) {
          res.observable[q] = 1;
          continue;
        }
        // nearest lattice point of the camera's vehicle position for a camera at x
        std::array<std::int64_t, 3> base{};
        for (int a = 0; a < 3; ++a) {
          const double c = (a == 2 ? x[a] - mount_z : x[a]) - origin[a];
          base[a] = static_cast<std::int64_t>(std::llround(c / step[a]));
        }
        for (const auto& o : offsets) {
          const std::int64_t i = base[0] + o[0], j = base[1] + o[1], k = base[2] + o[2];
          if (i < 0 || j < 0 || k < 0 || i >= dim[0] || j >= dim[1] || k >= dim[2]) continue;
          const std::int64_t f = flat(i, j, k);
          if (f == witness || !reach[static_cast<std::size_t>(f)]) continue;
          if (!sees(i, j, k)) continue;
          res.observable[q] = 1;
          witness = f;
          break;
        }
      }
    });
  res.timings_s.emplace_back("samples", seconds_since(t0));
  return res;
}

}  // namespace nbv
