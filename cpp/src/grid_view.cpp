#include "nbv/grid_view.hpp"

#include "nbv/occupancy_map.hpp"
#include "nbv/surface_observations.hpp"

#include <immintrin.h>

#include <algorithm>

#include <stdexcept>

namespace nbv {

GridView grid_view(const OccupancyMap& map, const SurfaceObservations* surface) {
  const WorkspaceGrid& w = map.grid();
  GridView g;
  g.resolution = map.resolution();
  g.origin = map.bounds_min();
  g.nx = w.dims()[0];
  g.ny = w.dims()[1];
  g.nz = w.dims()[2];
  g.layout = w.layout();
  g.scored = w.scored_data();
  g.logodds = w.logodds_data();
  g.flags = w.flag_data();
  g.brick_live = w.brick_live_data();
  g.brick_open = w.brick_open_data();
  g.unknown_entropy = float(w.rule().entropy(0.0f, CellFlag::Unknown));
  g.grid_stamps = w.stamps().data();
  g.grid_epoch = w.stamps().take_epoch();
  g.grid_id = w.stamps().id();
  if (surface) {
    if (!surface->matches(map))
      throw std::invalid_argument("surface observations were made for another map's grid");
    g.seen = surface->seen_data();
    g.hits = surface->hits_data();
    g.seen_stamps = surface->stamps().data();
    g.seen_epoch = surface->stamps().take_epoch();
    g.seen_id = surface->stamps().id();
  }
  return g;
}

bool GridView::cell_of(const Eigen::Vector3d& p, Eigen::Vector3i& c) const {
  const Eigen::Vector3d q = (p - origin) / resolution;
  c = q.array().floor().cast<int>();
  return contains(c.x(), c.y(), c.z());
}

void GridView::validate() const {
  if (!(resolution > 0) || nx <= 0 || ny <= 0 || nz <= 0 || !scored || !logodds || !flags ||
      !brick_live || !brick_open)
    throw std::invalid_argument("grid view is empty or incomplete");
}

RayOrigin ray_origin(const GridView& g, const Eigen::Vector3d& o) {
  RayOrigin r;
  r.pos = (o - g.origin) / g.resolution;  // as walk_ray
  const int n[3] = {g.nx, g.ny, g.nz};
  r.inside = true;
  for (int a = 0; a < 3; ++a) {
    r.inside &= r.pos[a] >= 0.0 && r.pos[a] < n[a];
    r.cell[a] = grid_cell(r.pos[a], n[a]);
  }
  return r;
}

bool ray_start(const GridView& g, const RayOrigin& origin, const Eigen::Vector3d& d, double t_max,
               RayStart& r) {
  const Eigen::Vector3d& pos = origin.pos;
  const int n[3] = {g.nx, g.ny, g.nz};
  int c[3];
  if (origin.inside) {
    // walk_ray's clip from inside the box: every axis's entry is at t <= 0, so t0 = 0 and the
    // first cell is the origin's; t1 is the least of the exits (the same quotients)
    double t1 = t_max / g.resolution;
    for (int a = 0; a < 3; ++a)
      if (d[a] != 0.0) t1 = std::min(t1, ((d[a] > 0 ? n[a] : 0.0) - pos[a]) / d[a]);
    if (!(0.0 <= t1)) return false;
    r.t1 = t1;
    for (int a = 0; a < 3; ++a) c[a] = origin.cell[a];
  } else {
    double t0, t1;
    if (!clip_to_grid(g, pos, d, t_max, t0, t1)) return false;
    r.t1 = t1;
    const Eigen::Vector3d p0 = pos + t0 * d;
    for (int a = 0; a < 3; ++a) c[a] = grid_cell(p0[a], n[a]);
  }
  int step[3];
  for (int a = 0; a < 3; ++a) dda_axis(d[a], c[a], pos[a], step[a], r.t_next[a], r.t_delta[a]);
  std::int64_t cross[3];
  dda_id_steps(g, step, r.step_in, cross);
  for (int a = 0; a < 3; ++a) {
    r.step_cross[a] = cross[a] - r.step_in[a];
    // steps left: n - 1 - c up, c down; + floor makes it 3 - (c & 3), c & 3 modulo 4
    r.floor[a] = step[a] > 0 ? (4 - n[a] % 4) % 4 : 0;
    r.countdown[a] = (step[a] > 0   ? n[a] - 1 - c[a]
                      : step[a] < 0 ? c[a]
                                    : std::int64_t(1) << 40) +
                     r.floor[a];
  }
  r.id = std::int64_t(g.layout.id(c[0], c[1], c[2]));
  return true;
}

namespace {

// One ray at a time: walk_ray's loop on RayStart's state.
void walk_rays4_scalar(const RayStart* starts, const bool* active, std::int64_t* cells, int* count,
                       int cap) {
  for (int l = 0; l < 4; ++l) {
    count[l] = 0;
    if (!active[l]) continue;
    RayStart r = starts[l];
    int j = 0;
    cells[l] = r.id;
    for (++j; j < cap; ++j) {
      if (std::min(std::min(r.t_next[0], r.t_next[1]), r.t_next[2]) > r.t1) break;
      const int a = (r.t_next[0] < r.t_next[1]) & (r.t_next[0] < r.t_next[2]) ? 0
                    : r.t_next[1] < r.t_next[2]                               ? 1
                                                                              : 2;
      r.t_next[a] += r.t_delta[a];
      r.id += r.step_in[a] + ((r.countdown[a] & 3) == 0 ? r.step_cross[a] : 0);
      if (--r.countdown[a] < r.floor[a]) break;
      cells[4 * j + l] = r.id;
    }
    count[l] = j;
  }
}

__attribute__((target("avx2"))) inline __m256i load4(const std::int64_t* p) {
  return _mm256_load_si256(reinterpret_cast<const __m256i*>(p));
}

// Per lane: a where x, else b where y, else c.
__attribute__((target("avx2"))) inline __m256i pick(__m256d x, __m256d y, __m256i a, __m256i b,
                                                    __m256i c) {
  const __m256d bc = _mm256_blendv_pd(_mm256_castsi256_pd(c), _mm256_castsi256_pd(b), y);
  return _mm256_castpd_si256(_mm256_blendv_pd(bc, _mm256_castsi256_pd(a), x));
}

// Four rays in the lanes of AVX2 registers: the same comparisons and additions, the axis of each
// lane's step chosen by masks.
__attribute__((target("avx2"))) void walk_rays4_avx2(const RayStart* starts, const bool* active,
                                                     std::int64_t* cells, int* count, int cap) {
  alignas(32) double dv[7][4];
  alignas(32) std::int64_t iv[13][4];
  int any = 0;  // an idle lane repeats an active one's start
  while (any < 3 && !active[any]) ++any;
  for (int l = 0; l < 4; ++l) {
    const RayStart& r = starts[active[l] ? l : any];
    for (int a = 0; a < 3; ++a) {
      dv[a][l] = r.t_next[a];
      dv[3 + a][l] = r.t_delta[a];
      iv[1 + a][l] = r.countdown[a];
      iv[4 + a][l] = r.floor[a];
      iv[7 + a][l] = r.step_in[a];
      iv[10 + a][l] = r.step_cross[a];
    }
    dv[6][l] = r.t1;
    iv[0][l] = r.id;
  }
  __m256d tn0 = _mm256_load_pd(dv[0]), tn1 = _mm256_load_pd(dv[1]), tn2 = _mm256_load_pd(dv[2]);
  const __m256d td0 = _mm256_load_pd(dv[3]), td1 = _mm256_load_pd(dv[4]);
  const __m256d td2 = _mm256_load_pd(dv[5]), t1 = _mm256_load_pd(dv[6]);
  __m256i id = load4(iv[0]), k0 = load4(iv[1]), k1 = load4(iv[2]), k2 = load4(iv[3]);
  const __m256i f0 = load4(iv[4]), f1 = load4(iv[5]), f2 = load4(iv[6]);
  const __m256i in0 = load4(iv[7]), in1 = load4(iv[8]), in2 = load4(iv[9]);
  const __m256i cr0 = load4(iv[10]), cr1 = load4(iv[11]), cr2 = load4(iv[12]);
  const __m256i zero = _mm256_setzero_si256(), three = _mm256_set1_epi64x(3);
  const __m256i one = _mm256_set1_epi64x(1);
  __m256i alive = _mm256_set_epi64x(-std::int64_t(active[3]), -std::int64_t(active[2]),
                                    -std::int64_t(active[1]), -std::int64_t(active[0]));
  __m256i n = _mm256_sub_epi64(zero, alive);  // each lane's cells so far
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(cells), id);
  for (int j = 1; j < cap && !_mm256_testz_si256(alive, alive); ++j) {
    const __m256d t_cross = _mm256_min_pd(_mm256_min_pd(tn0, tn1), tn2);
    alive = _mm256_and_si256(alive, _mm256_castpd_si256(_mm256_cmp_pd(t_cross, t1, _CMP_LE_OQ)));
    // walk_ray's choice: x only if strictly first, else y if strictly before z, else z
    const __m256d x =
        _mm256_and_pd(_mm256_cmp_pd(tn0, tn1, _CMP_LT_OQ), _mm256_cmp_pd(tn0, tn2, _CMP_LT_OQ));
    const __m256d y = _mm256_andnot_pd(x, _mm256_cmp_pd(tn1, tn2, _CMP_LT_OQ));
    const __m256d xy = _mm256_or_pd(x, y);
    tn0 = _mm256_add_pd(tn0, _mm256_and_pd(x, td0));  // + 0.0 leaves the others as they are
    tn1 = _mm256_add_pd(tn1, _mm256_and_pd(y, td1));
    tn2 = _mm256_add_pd(tn2, _mm256_andnot_pd(xy, td2));
    const __m256i k = pick(x, y, k0, k1, k2);  // the stepping axis's countdown
    const __m256i edge = _mm256_cmpeq_epi64(_mm256_and_si256(k, three), zero);
    id = _mm256_add_epi64(id, _mm256_add_epi64(pick(x, y, in0, in1, in2),
                                               _mm256_and_si256(edge, pick(x, y, cr0, cr1, cr2))));
    // a mask is -1 where its axis stepped; the ray leaves the grid when its countdown drops
    // below the floor
    k0 = _mm256_add_epi64(k0, _mm256_castpd_si256(x));
    k1 = _mm256_add_epi64(k1, _mm256_castpd_si256(y));
    k2 = _mm256_sub_epi64(_mm256_sub_epi64(k2, one), _mm256_castpd_si256(xy));
    alive = _mm256_and_si256(alive, _mm256_cmpgt_epi64(k, pick(x, y, f0, f1, f2)));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(cells + 4 * j), id);
    n = _mm256_sub_epi64(n, alive);
  }
  alignas(32) std::int64_t nn[4];
  _mm256_store_si256(reinterpret_cast<__m256i*>(nn), n);
  for (int l = 0; l < 4; ++l) count[l] = int(nn[l]);
}

}  // namespace

void walk_rays4(const GridView& g, const RayStart* starts, const bool* active, std::int64_t* cells,
                int* count, bool simd) {
  static const bool avx2 = __builtin_cpu_supports("avx2");
  if (!(active[0] | active[1] | active[2] | active[3])) {
    std::fill(count, count + 4, 0);
    return;
  }
  if (simd && avx2)
    walk_rays4_avx2(starts, active, cells, count, max_ray_cells(g));
  else
    walk_rays4_scalar(starts, active, cells, count, max_ray_cells(g));
}

int direction_bin(const Eigen::Vector3d& d) {
  // Each component becomes -1, 0 or 1: 0 where it is small against the largest
  // (|d_a| <= tan(22.5 deg) max|d|), so in each coordinate plane the bin is the nearest of the
  // eight directions; elsewhere it approximates the nearest of the 26.
  constexpr double kTan22_5 = 0.41421356237309503;
  const Eigen::Vector3d a = d.cwiseAbs();
  const double t = kTan22_5 * a.maxCoeff();
  int b = 0, mul = 1;
  for (int k = 0; k < 3; ++k, mul *= 3) b += mul * (a[k] > t ? (d[k] > 0 ? 2 : 0) : 1);
  return b < 13 ? b : b - 1;  // 13 is the zero vector
}

Eigen::Vector3d bin_direction(int b) {
  if (b < 0 || b > 25) throw std::invalid_argument("direction bin must be in 0..25");
  const int v = b < 13 ? b : b + 1;
  return Eigen::Vector3d(v % 3 - 1, (v / 3) % 3 - 1, v / 9 - 1).normalized();
}

std::uint32_t bin_cone(int b, double cone_deg) {
  const double c = std::cos(cone_deg * M_PI / 180.0) - 1e-12;
  const Eigen::Vector3d d = bin_direction(b);
  std::uint32_t mask = 0;
  for (int k = 0; k < 26; ++k)
    if (bin_direction(k).dot(d) >= c) mask |= std::uint32_t(1) << k;
  return mask;
}

}  // namespace nbv
