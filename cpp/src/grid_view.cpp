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
  g.cells = w.cells();
  g.brick_live = w.brick_live_data();
  g.brick_open = w.brick_open_data();
  g.brick_occupied = w.brick_occupied_data();
  g.unknown_entropy = float(w.rule().entropy(0.0f, CellFlag::Unknown));
  g.predicted_cells = w.counts().predicted;
  g.grid_stamps = w.stamps().data();
  g.grid_epoch = w.stamps().take_epoch();
  g.grid_id = w.stamps().id();
  if (surface) {
    if (!surface->matches(map))
      throw std::invalid_argument("surface observations were made for another map's grid");
    g.seen_blocks = surface->brick_blocks();
    g.seen_pool = surface->seen_pool();
    g.hits_pool = surface->hits_pool();
    g.patches_pool = surface->patches_pool();
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
  if (!(resolution > 0) || nx <= 0 || ny <= 0 || nz <= 0 || !cells || !brick_live || !brick_open ||
      !brick_occupied)
    throw std::invalid_argument("grid view is empty or incomplete");
}

namespace {

// RayStart's countdown of the steps left in the grid along an axis of n cells for a ray from
// cell c stepping by `step`, and its floor: steps left n - 1 - c up, c down; + floor makes it
// 3 - (c & 3), c & 3 modulo 4 (a step crosses a brick boundary where it is a multiple of 4).
void dda_countdown(int step, int c, int n, std::int64_t& floor, std::int64_t& countdown) {
  floor = step > 0 ? (4 - n % 4) % 4 : 0;
  countdown = (step > 0 ? n - 1 - c : step < 0 ? c : std::int64_t(1) << 40) + floor;
}

}  // namespace

RayOrigin ray_origin(const GridView& g, const Eigen::Vector3d& o) {
  RayOrigin r;
  r.pos = (o - g.origin) / g.resolution;  // as walk_ray
  const int n[3] = {g.nx, g.ny, g.nz};
  r.inside = true;
  for (int a = 0; a < 3; ++a) {
    r.inside &= r.pos[a] >= 0.0 && r.pos[a] < n[a];
    r.cell[a] = grid_cell(r.pos[a], n[a]);
  }
  if (!r.inside) return r;
  r.id = std::int64_t(g.layout.id(r.cell[0], r.cell[1], r.cell[2]));
  for (int k = 0; k < 3; ++k) {  // ray_start's steps, countdowns and floors from this cell
    const int s = k == 0 ? 1 : k == 1 ? -1 : 0, step[3] = {s, s, s};
    std::int64_t in[3], cross[3];
    dda_id_steps(g, step, in, cross);
    for (int a = 0; a < 3; ++a) {
      r.step_in[a][k] = in[a];
      r.step_cross[a][k] = cross[a] - in[a];
      dda_countdown(s, r.cell[a], n[a], r.floor[a][k], r.countdown[a][k]);
    }
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
    dda_countdown(step[a], c[a], n[a], r.floor[a], r.countdown[a]);
  }
  r.id = std::int64_t(g.layout.id(c[0], c[1], c[2]));
  return true;
}

namespace {

// ray_start's arithmetic from an origin inside the grid, four rays in the lanes of AVX2
// registers: the same quotients, differences and minima, lane by lane (IEEE operations give
// the same bits in a lane as in a scalar register).
__attribute__((target("avx2"))) void ray_starts4_avx2(const GridView& g, const RayOrigin& origin,
                                                      const double* const* d, const double* t_max,
                                                      RayStart* r, bool* active) {
  const int n[3] = {g.nx, g.ny, g.nz};
  const __m256d zero = _mm256_setzero_pd(), one = _mm256_set1_pd(1.0);
  const __m256d inf = _mm256_set1_pd(std::numeric_limits<double>::infinity());
  __m256d t1 = _mm256_div_pd(_mm256_loadu_pd(t_max), _mm256_set1_pd(g.resolution));
  alignas(32) double t_next[3][4], t_delta[3][4];
  int up[3], down[3];
  for (int a = 0; a < 3; ++a) {
    const __m256d da = _mm256_loadu_pd(d[a]), p = _mm256_set1_pd(origin.pos[a]);
    const __m256d gt = _mm256_cmp_pd(da, zero, _CMP_GT_OQ),
                  lt = _mm256_cmp_pd(da, zero, _CMP_LT_OQ);
    const __m256d moving = _mm256_or_pd(gt, lt);
    // t1 = min(t1, ((d > 0 ? n : 0) - p) / d) where d != 0, as std::min(t1, q): q if q < t1
    const __m256d q = _mm256_div_pd(_mm256_sub_pd(_mm256_and_pd(gt, _mm256_set1_pd(n[a])), p), da);
    t1 = _mm256_blendv_pd(t1, _mm256_min_pd(q, t1), moving);
    // dda_axis: 1 / d and (c + 1 - p) / d up, -1 / d and (c - p) / d down, infinity otherwise
    const __m256d c = _mm256_set1_pd(origin.cell[a]);
    const __m256d delta = _mm256_div_pd(_mm256_blendv_pd(_mm256_set1_pd(-1.0), one, gt), da);
    const __m256d next = _mm256_div_pd(
        _mm256_sub_pd(_mm256_blendv_pd(c, _mm256_set1_pd(origin.cell[a] + 1), gt), p), da);
    _mm256_store_pd(t_delta[a], _mm256_blendv_pd(inf, delta, moving));
    _mm256_store_pd(t_next[a], _mm256_blendv_pd(inf, next, moving));
    up[a] = _mm256_movemask_pd(gt);
    down[a] = _mm256_movemask_pd(lt);
  }
  const int reached = _mm256_movemask_pd(_mm256_cmp_pd(zero, t1, _CMP_LE_OQ));
  alignas(32) double t1s[4];
  _mm256_store_pd(t1s, t1);
  for (int l = 0; l < 4; ++l) {
    active[l] = reached >> l & 1;
    RayStart& s = r[l];
    s.t1 = t1s[l];
    s.id = origin.id;
    for (int a = 0; a < 3; ++a) {  // the rest depends on the step's sign alone (RayOrigin)
      const int k = up[a] >> l & 1 ? 0 : down[a] >> l & 1 ? 1 : 2;
      s.t_next[a] = t_next[a][l];
      s.t_delta[a] = t_delta[a][l];
      s.step_in[a] = origin.step_in[a][k];
      s.step_cross[a] = origin.step_cross[a][k];
      s.floor[a] = origin.floor[a][k];
      s.countdown[a] = origin.countdown[a][k];
    }
  }
}

}  // namespace

void ray_starts4(const GridView& g, const RayOrigin& origin, const double* const* d,
                 const double* t_max, RayStart* r, bool* active, bool simd) {
  static const bool avx2 = __builtin_cpu_supports("avx2");
  if (simd && avx2 && origin.inside) return ray_starts4_avx2(g, origin, d, t_max, r, active);
  for (int l = 0; l < 4; ++l)
    active[l] = ray_start(g, origin, {d[0][l], d[1][l], d[2][l]}, t_max[l], r[l]);
}

namespace {

__attribute__((target("avx2"))) inline __m256i load4(const std::int64_t* p) {
  return _mm256_load_si256(reinterpret_cast<const __m256i*>(p));
}

// Per lane: a where x, else b where y, else c.
__attribute__((target("avx2"))) inline __m256i pick(__m256d x, __m256d y, __m256i a, __m256i b,
                                                    __m256i c) {
  const __m256d bc = _mm256_blendv_pd(_mm256_castsi256_pd(c), _mm256_castsi256_pd(b), y);
  return _mm256_castpd_si256(_mm256_blendv_pd(bc, _mm256_castsi256_pd(a), x));
}

// One step of walk_ray's loop on RayStart's state, to the ray's next cell; false where the ray
// ends at its cell (its next boundary past t1, or the step off the grid).
inline bool step_ray(RayStart& r) {
  if (std::min(std::min(r.t_next[0], r.t_next[1]), r.t_next[2]) > r.t1) return false;
  const int a = (r.t_next[0] < r.t_next[1]) & (r.t_next[0] < r.t_next[2]) ? 0
                : r.t_next[1] < r.t_next[2]                               ? 1
                                                                          : 2;
  r.t_next[a] += r.t_delta[a];
  r.id += r.step_in[a] + ((r.countdown[a] & 3) == 0 ? r.step_cross[a] : 0);
  return --r.countdown[a] >= r.floor[a];
}

// One ray at a time: walk_ray's loop on RayStart's state, each cell marked as it is entered.
void mark_rays4_scalar(const GridView& g, const RayStart* starts, const bool* active,
                       CellMarks& marks, std::size_t* stop, int cap) {
  for (int l = 0; l < 4; ++l) {
    stop[l] = kNoCell;
    if (!active[l]) continue;
    RayStart r = starts[l];
    for (int j = 0;;) {
      const auto id = std::size_t(r.id);
      const std::uint64_t old = marks.bits[id >> 6];
      marks.bits[id >> 6] = old | std::uint64_t(1) << (id & 63);
      marks.touched[marks.n_touched] = std::uint32_t(id >> 6);
      marks.n_touched += old == 0;
      if (g.cells.occupied(id)) {
        stop[l] = id;
        break;
      }
      if (++j >= cap || !step_ray(r)) break;
    }
  }
}

// The 3D-DDA of four rays from their RayStarts in the lanes of AVX2 registers, with walk_ray's
// comparisons and additions (the stepping axis chosen by masks): `id` the lanes' cells, `alive`
// the lanes still in their ray. An idle lane repeats an active one's start.
struct Lanes {
  __m256d tn0, tn1, tn2, td0, td1, td2, t1;
  __m256i id, k0, k1, k2, f0, f1, f2, in0, in1, in2, cr0, cr1, cr2, alive;

  __attribute__((target("avx2"))) Lanes(const RayStart* starts, const bool* active) {
    alignas(32) double dv[7][4];
    alignas(32) std::int64_t iv[13][4];
    int any = 0;
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
    tn0 = _mm256_load_pd(dv[0]), tn1 = _mm256_load_pd(dv[1]), tn2 = _mm256_load_pd(dv[2]);
    td0 = _mm256_load_pd(dv[3]), td1 = _mm256_load_pd(dv[4]), td2 = _mm256_load_pd(dv[5]);
    t1 = _mm256_load_pd(dv[6]);
    id = load4(iv[0]), k0 = load4(iv[1]), k1 = load4(iv[2]), k2 = load4(iv[3]);
    f0 = load4(iv[4]), f1 = load4(iv[5]), f2 = load4(iv[6]);
    in0 = load4(iv[7]), in1 = load4(iv[8]), in2 = load4(iv[9]);
    cr0 = load4(iv[10]), cr1 = load4(iv[11]), cr2 = load4(iv[12]);
    alive = _mm256_set_epi64x(-std::int64_t(active[3]), -std::int64_t(active[2]),
                              -std::int64_t(active[1]), -std::int64_t(active[0]));
  }

  // One step of every lane to its next cell; returns the lanes whose step crossed a brick
  // boundary. A lane whose ray ends at its cell (past t1, or off the grid) is no longer alive.
  __attribute__((target("avx2"), always_inline)) __m256i step() {
    const __m256i zero = _mm256_setzero_si256(), three = _mm256_set1_epi64x(3);
    const __m256i one = _mm256_set1_epi64x(1);
    const __m256d t_cross = _mm256_min_pd(_mm256_min_pd(tn0, tn1), tn2);
    alive = _mm256_and_si256(alive, _mm256_castpd_si256(_mm256_cmp_pd(t_cross, t1, _CMP_LE_OQ)));
    const __m256d x =
        _mm256_and_pd(_mm256_cmp_pd(tn0, tn1, _CMP_LT_OQ), _mm256_cmp_pd(tn0, tn2, _CMP_LT_OQ));
    const __m256d y = _mm256_andnot_pd(x, _mm256_cmp_pd(tn1, tn2, _CMP_LT_OQ));
    const __m256d xy = _mm256_or_pd(x, y);
    tn0 = _mm256_add_pd(tn0, _mm256_and_pd(x, td0));
    tn1 = _mm256_add_pd(tn1, _mm256_and_pd(y, td1));
    tn2 = _mm256_add_pd(tn2, _mm256_andnot_pd(xy, td2));
    const __m256i k = pick(x, y, k0, k1, k2);
    const __m256i edge = _mm256_cmpeq_epi64(_mm256_and_si256(k, three), zero);
    id = _mm256_add_epi64(id, _mm256_add_epi64(pick(x, y, in0, in1, in2),
                                               _mm256_and_si256(edge, pick(x, y, cr0, cr1, cr2))));
    k0 = _mm256_add_epi64(k0, _mm256_castpd_si256(x));
    k1 = _mm256_add_epi64(k1, _mm256_castpd_si256(y));
    k2 = _mm256_sub_epi64(_mm256_sub_epi64(k2, one), _mm256_castpd_si256(xy));
    alive = _mm256_and_si256(alive, _mm256_cmpgt_epi64(k, pick(x, y, f0, f1, f2)));
    return edge;
  }
};

// Four rays in the lanes of AVX2 registers, with walk_ray's comparisons and additions (the
// stepping axis chosen by masks). Per step, each lane writes its cell's id and its run: the
// mask of the ray's cells so far in the current brick; and the lanes whose run ends there (the
// ray leaves the brick or the grid) go into a byte per step. Then, ray by ray, the runs are put
// into the set, each with one read and one write of its word; a run's cells are read only in a
// brick that holds an occupied cell, up to the ray's first (where the ray stops, with the run
// so far). Marked cell by cell, each mark waited on the one before it in the same word, and
// there are about four visits for each distinct cell of a view.
__attribute__((target("avx2"))) void mark_rays4_avx2(const GridView& g, const RayStart* starts,
                                                     const bool* active, CellMarks& marks,
                                                     const MarkBuffer& buffer, std::size_t* stop,
                                                     int cap) {
  Lanes lanes(starts, active);
  const __m256i zero = _mm256_setzero_si256();
  const __m256i one = _mm256_set1_epi64x(1), low6 = _mm256_set1_epi64x(63);
  __m256i run = _mm256_sllv_epi64(one, _mm256_and_si256(lanes.id, low6));
  auto* cells = reinterpret_cast<__m256i*>(buffer.cells);
  auto* runs = reinterpret_cast<__m256i*>(buffer.runs);
  std::uint8_t* ends_at = buffer.ends;
  int steps = 0;
  while (steps < cap) {
    const __m256i was = lanes.alive, here = lanes.id;
    const __m256i edge = lanes.step();
    const __m256i alive = lanes.alive;
    // this cell's run ends where the ray leaves its brick or the grid
    const __m256i ends = _mm256_and_si256(was, _mm256_or_si256(edge, _mm256_xor_si256(was, alive)));
    _mm256_storeu_si256(cells + steps, here);
    _mm256_storeu_si256(runs + steps, run);
    ends_at[steps] = std::uint8_t(_mm256_movemask_pd(_mm256_castsi256_pd(ends)));
    ++steps;
    run = _mm256_or_si256(_mm256_andnot_si256(ends, run),
                          _mm256_sllv_epi64(one, _mm256_and_si256(lanes.id, low6)));
    if (_mm256_testz_si256(alive, alive)) break;
  }
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(ends_at + steps), zero);
  // Lane by lane, its run ends 32 steps at a time: bit l of each step's byte moved to bit 7
  const CellPools pools = g.cells;
  const std::uint8_t* occupied = g.brick_occupied;
  const std::uint64_t* ids = buffer.cells;
  const std::uint64_t* masks = buffer.runs;
  std::uint64_t* bits = marks.bits;
  std::uint32_t* touched = marks.touched;
  std::size_t n_touched = marks.n_touched;
  for (int l = 0; l < 4; ++l) {
    stop[l] = kNoCell;
    int first = 0;  // the current run's first step
    bool stopped = false;
    for (int b = 0; b < steps && !stopped; b += 32) {
      const __m256i e8 = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(ends_at + b));
      auto e = unsigned(_mm256_movemask_epi8(_mm256_slli_epi16(e8, 7 - l)));
      for (; e; e &= e - 1) {
        const int j = b + __builtin_ctz(e);
        const std::size_t w = ids[4 * j + l] >> 6;
        std::uint64_t mask = masks[4 * j + l];
        if (occupied[w]) {
          for (int i = first; i <= j; ++i) {
            const std::uint64_t c = ids[4 * i + l];
            if (pools.occupied(c)) {
              mask = masks[4 * i + l];
              stop[l] = c;
              stopped = true;
              break;
            }
          }
        }
        const std::uint64_t old = bits[w];
        bits[w] = old | mask;
        touched[n_touched] = std::uint32_t(w);
        n_touched += old == 0;
        if (stopped) break;
        first = j + 1;
      }
    }
  }
  marks.n_touched = n_touched;
}

// Eight cells at a time in AVX2 lanes (a byte of a word: its scores, masked by its bits), in
// double: the lanes' sums are exact under sum_marked's condition, in any order.
__attribute__((target("avx2"))) bool sum_marked_avx2(const GridView& g, const std::uint32_t* words,
                                                     std::size_t n_words, const std::uint64_t* bits,
                                                     double& gain, int& cells) {
  const __m256i bit = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
  const __m256i magnitude_mask = _mm256_set1_epi32(0x7FFFFFFF);
  const __m256i zero = _mm256_setzero_si256();
  const __m256i tiny = _mm256_set1_epi32(std::int32_t(std::uint32_t(127 - 8) << 23));
  __m256d acc0 = _mm256_setzero_pd(), acc1 = _mm256_setzero_pd();
  __m256i small = zero;
  int n = 0;
  for (std::size_t i = 0; i < n_words; ++i) {
    const std::uint32_t w = words[i];
    if (!g.brick_live[w]) continue;  // a neutral brick stepped over
    const std::uint64_t m = bits[w];
    const float* s = g.cells.brick_scored(w);
    for (int half = 0; half < 8; ++half) {
      const auto byte = std::int32_t((m >> (8 * half)) & 0xFF);
      if (!byte) continue;
      const __m256i lanes = _mm256_cmpeq_epi32(_mm256_and_si256(_mm256_set1_epi32(byte), bit), bit);
      const __m256i v = _mm256_and_si256(
          _mm256_and_si256(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(s + 8 * half)),
                           magnitude_mask),
          lanes);
      const __m256i nonzero = _mm256_cmpgt_epi32(v, zero);
      small = _mm256_or_si256(small, _mm256_and_si256(nonzero, _mm256_cmpgt_epi32(tiny, v)));
      n += __builtin_popcount(unsigned(_mm256_movemask_ps(_mm256_castsi256_ps(nonzero))));
      const __m256 f = _mm256_castsi256_ps(v);
      acc0 = _mm256_add_pd(acc0, _mm256_cvtps_pd(_mm256_castps256_ps128(f)));
      acc1 = _mm256_add_pd(acc1, _mm256_cvtps_pd(_mm256_extractf128_ps(f, 1)));
    }
  }
  alignas(32) double a[4];
  _mm256_store_pd(a, _mm256_add_pd(acc0, acc1));
  gain = (a[0] + a[1]) + (a[2] + a[3]);
  cells = n;
  return _mm256_testz_si256(small, small) && gain < 4194304.0;  // 2^22
}

// step_rays4 one ray at a time: walk_ray's loop on RayStart's state.
void step_rays4_scalar(const RayStart* starts, const bool* active, std::uint64_t* ids, int* count,
                       int cap) {
  for (int l = 0; l < 4; ++l) {
    count[l] = 0;
    if (!active[l]) continue;
    RayStart r = starts[l];
    for (int j = 0;;) {
      ids[4 * j + l] = std::uint64_t(r.id);
      count[l] = ++j;
      if (j >= cap || !step_ray(r)) break;
    }
  }
}

// step_rays4 in the lanes of AVX2 registers: mark_rays4_avx2's steps, writing the ids alone.
__attribute__((target("avx2"))) void step_rays4_avx2(const RayStart* starts, const bool* active,
                                                     std::uint64_t* ids, int* count, int cap) {
  Lanes lanes(starts, active);
  __m256i cells = _mm256_setzero_si256();  // per lane, the cells written while it was alive
  auto* out = reinterpret_cast<__m256i*>(ids);
  for (int steps = 0; steps < cap; ++steps) {
    _mm256_storeu_si256(out + steps, lanes.id);
    cells = _mm256_sub_epi64(cells, lanes.alive);
    lanes.step();
    if (_mm256_testz_si256(lanes.alive, lanes.alive)) break;
  }
  alignas(32) std::int64_t n[4];
  _mm256_store_si256(reinterpret_cast<__m256i*>(n), cells);
  for (int l = 0; l < 4; ++l) count[l] = active[l] ? int(n[l]) : 0;
}

}  // namespace

void step_rays4(const GridView& g, const RayStart* starts, const bool* active, std::uint64_t* ids,
                int* count, bool simd) {
  static const bool avx2 = __builtin_cpu_supports("avx2");
  if (!(active[0] | active[1] | active[2] | active[3])) {
    std::fill(count, count + 4, 0);
    return;
  }
  if (simd && avx2)
    step_rays4_avx2(starts, active, ids, count, max_ray_cells(g));
  else
    step_rays4_scalar(starts, active, ids, count, max_ray_cells(g));
}

bool sum_marked(const GridView& g, const std::uint32_t* words, std::size_t n_words,
                const std::uint64_t* bits, double& gain, int& cells, bool simd) {
  static const bool avx2 = __builtin_cpu_supports("avx2");
  if (simd && avx2) return sum_marked_avx2(g, words, n_words, bits, gain, cells);
  double sum = 0.0;
  int n = 0;
  std::uint32_t small = 0;
  for (std::size_t i = 0; i < n_words; ++i)
    if (g.brick_live[words[i]])
      sum_cells(g.cells.brick_scored(words[i]), bits[words[i]], sum, n, small);
  gain = sum;
  cells = n;
  return small == 0 && sum < 4194304.0;  // 2^22
}

void mark_rays4(const GridView& g, const RayStart* starts, const bool* active, CellMarks& marks,
                const MarkBuffer& buffer, std::size_t* stop, bool simd) {
  static const bool avx2 = __builtin_cpu_supports("avx2");
  if (!(active[0] | active[1] | active[2] | active[3])) {
    std::fill(stop, stop + 4, kNoCell);
    return;
  }
  if (simd && avx2)
    mark_rays4_avx2(g, starts, active, marks, buffer, stop, max_ray_cells(g));
  else
    mark_rays4_scalar(g, starts, active, marks, stop, max_ray_cells(g));
}

Eigen::Vector3d bin_direction(int b) {
  if (b < 0 || b > 25) throw std::invalid_argument("direction bin must be in 0..25");
  const int v = b < 13 ? b : b + 1;
  return Eigen::Vector3d(v % 3 - 1, (v / 3) % 3 - 1, v / 9 - 1).normalized();
}

std::array<std::uint32_t, 26> bin_cones(double cone_deg) {
  std::array<std::uint32_t, 26> cones;
  for (int b = 0; b < 26; ++b) cones[std::size_t(b)] = bin_cone(b, cone_deg);
  return cones;
}

std::uint32_t bin_cone(int b, double cone_deg) {
  if (!(cone_deg >= 0 && cone_deg <= 180))  // (a NaN cone took every bin or none)
    throw std::invalid_argument("cone_deg must be in [0, 180] degrees, got " + fmt(cone_deg));
  const double c = std::cos(cone_deg * M_PI / 180.0) - 1e-12;
  const Eigen::Vector3d d = bin_direction(b);
  std::uint32_t mask = 0;
  for (int k = 0; k < 26; ++k)
    if (bin_direction(k).dot(d) >= c) mask |= std::uint32_t(1) << k;
  return mask;
}

}  // namespace nbv
