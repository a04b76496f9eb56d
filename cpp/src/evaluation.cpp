#include "nbv/evaluation.hpp"

#include "nbv/huge_pages.hpp"
#include "nbv/parallel.hpp"
#include "nbv/point_cloud.hpp"

#include <tbb/parallel_invoke.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <mutex>
#include <sstream>

namespace nbv {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

}  // namespace

// ---------------------------------------------------------------------------- evaluation

void EvaluationOptions::validate() const {
  // a micrometre to a kilometre: beyond, a unit's mistake (1e308 m read as 100 % coverage)
  for (double r : resolutions) require_cell_size(r, "resolutions");
  for (double t : taus) require_cell_size(t, "taus");
  for (const auto* v : {&resolutions, &taus})
    for (std::size_t i = 0; i < v->size(); ++i)
      if (std::find(v->begin(), v->begin() + i, (*v)[i]) != v->begin() + i)
        throw std::invalid_argument(std::string(v == &taus ? "taus" : "resolutions") +
                                    " has duplicate values: " + fmt((*v)[i]));
  if (!(std::isfinite(gt_density) && gt_density > 0))
    throw std::invalid_argument("gt_density must be a positive number of points per m^2, got " +
                                fmt(gt_density));
  if (max_gt_points < 1) throw std::invalid_argument("max_gt_points must be >= 1");
  if (part_points < 1) throw std::invalid_argument("part_points must be >= 1");
}

namespace {

// Cell keys of n points point_at(0 .. n - 1) into out[0 .. n) (parallel); false if a point is
// too far from the origin for the grid (its key is kEmptyVoxelKey).
template <class PointAt>
bool fill_cell_keys(std::uint64_t* out, std::size_t n, const PointAt& point_at, double r) {
  std::atomic<bool> bad{false};
  const double inv = 1.0 / r;
  parallel_chunks(n, 1 << 14, [&](std::size_t b, std::size_t e) {
    for (std::size_t k = b; k < e; ++k) {
      const Eigen::Vector3d p = point_at(k);
      out[k] = try_cell_key(p.x(), p.y(), p.z(), r, inv);
      if (out[k] == kEmptyVoxelKey) bad = true;
    }
  });
  return !bad;
}

[[noreturn]] void throw_too_far(const char* what, double r) {
  throw std::invalid_argument(std::string(what) + " has points too far from the origin for a " +
                              fmt(r) + " m grid (at most 2^20 cells per axis)");
}

template <class PointAt>
std::vector<std::uint64_t> cell_keys(std::size_t n, const PointAt& point_at, double r,
                                     const char* what) {
  std::vector<std::uint64_t> keys(n);
  if (!fill_cell_keys(keys.data(), n, point_at, r)) throw_too_far(what, r);
  return keys;
}

// The slab of each point of a cloud of n points (point(i)) along the axis of its bounding box's
// longest side, each slab of at most `most` points unless one of 4096 equal bins along the axis
// holds more (at most 256 slabs; each holds a point). Deterministic: bins
// from the same arithmetic in every pass.
std::vector<std::uint8_t> cloud_slabs(std::size_t n,
                                      const std::function<Eigen::Vector3d(std::size_t)>& point,
                                      std::size_t most) {
  constexpr std::size_t kBins = 4096;
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;
  std::mutex m;
  parallel_chunks(n, 1 << 16, [&](std::size_t b, std::size_t e) {
    Eigen::Vector3d l = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), h = -l;
    for (std::size_t i = b; i < e; ++i) {
      const Eigen::Vector3d p = point(i);
      l = l.cwiseMin(p);
      h = h.cwiseMax(p);
    }
    std::lock_guard<std::mutex> lock(m);
    lo = lo.cwiseMin(l);
    hi = hi.cwiseMax(h);
  });
  int axis = 0;
  (hi - lo).maxCoeff(&axis);
  const double a0 = lo[axis], scale = hi[axis] > a0 ? kBins / (hi[axis] - a0) : 0.0;
  const auto bin = [&](std::size_t i) {
    return std::min(kBins - 1, static_cast<std::size_t>((point(i)[axis] - a0) * scale));
  };
  std::vector<std::uint8_t> slab_of_bin(kBins);
  {
    std::vector<std::size_t> count(kBins, 0);
    parallel_chunks(n, 1 << 16, [&](std::size_t b, std::size_t e) {
      std::vector<std::size_t> c(kBins, 0);
      for (std::size_t i = b; i < e; ++i) ++c[bin(i)];
      std::lock_guard<std::mutex> lock(m);
      for (std::size_t k = 0; k < kBins; ++k) count[k] += c[k];
    });
    std::size_t slab = 0, in_slab = 0;
    for (std::size_t k = 0; k < kBins; ++k) {
      if (in_slab > 0 && count[k] > 0 && in_slab + count[k] > most && slab < 255) {
        ++slab;
        in_slab = 0;
      }
      slab_of_bin[k] = static_cast<std::uint8_t>(slab);
      in_slab += count[k];
    }
  }
  std::vector<std::uint8_t> slab(n);
  parallel_chunks(n, 1 << 16, [&](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i) slab[i] = slab_of_bin[bin(i)];
  });
  return slab;
}

double ratio(std::int64_t a, std::int64_t b) { return b > 0 ? static_cast<double>(a) / b : 0.0; }

}  // namespace

std::pair<Points, EvaluationResult> Evaluator::sample_mesh(const Mesh& gt,
                                                           const EvaluationOptions& options) {
  std::pair<Points, EvaluationResult> out;
  EvaluationResult& res = out.second;
  options.validate();
  res.from_mesh = true;
  res.seed = options.seed;
  res.gt_area = gt.area();
  const double density = options.gt_density;
  const double want = res.gt_area * density;
  std::size_t n = static_cast<std::size_t>(std::llround(std::min(want, 1e18)));
  if (want > static_cast<double>(options.max_gt_points)) {
    n = options.max_gt_points;
    res.warnings.push_back("ground truth: " + fmt(res.gt_area) + " m^2 at " + fmt(density) +
                           " points/m^2 would be " + fmt(want) + " samples; capped at " +
                           std::to_string(n) + " (" + fmt(static_cast<double>(n) / res.gt_area) +
                           " points/m^2)");
  }
  if (n == 0)
    throw std::invalid_argument("gt_density " + fmt(density) + " points/m^2 over the mesh's " +
                                fmt(res.gt_area) + " m^2 gives no ground-truth samples");
  res.gt_density = static_cast<double>(n) / res.gt_area;
  const auto t0 = std::chrono::steady_clock::now();
  out.first = gt.sample_surface(n, options.seed);
  res.timings_s.emplace_back("sample", seconds_since(t0));
  return out;
}

namespace {

const PointsRef& checked_gt(const PointsRef& gt, const EvaluationOptions& options) {
  options.validate();
  require_finite(gt, "ground truth");
  if (gt.rows() == 0) throw std::invalid_argument("ground truth point cloud is empty");
  return gt;
}

}  // namespace

Evaluator::Evaluator(const Mesh& gt, const EvaluationOptions& options)
    : Evaluator(sample_mesh(gt, options), options) {
  const std::size_t mesh_bytes =
      std::size_t(gt.vertices.size()) * sizeof(double) + std::size_t(gt.faces.size()) * 4;
  if (mesh_bytes < n_gt_ * 3 * sizeof(double) / 2) {  // the samples, drawn again when needed
    mesh_ = std::make_shared<const Mesh>(gt);
    gt_ = Points();
  }
}

Evaluator::Evaluator(std::pair<Points, EvaluationResult>&& sampled,
                     const EvaluationOptions& options)
    : Evaluator(sampled.first, options, std::move(sampled.second)) {}

Evaluator::Evaluator(const PointsRef& gt_points, const EvaluationOptions& options)
    : Evaluator(checked_gt(gt_points, options), options, EvaluationResult{}) {}

Evaluator::Evaluator(const PointsRef& gt, const EvaluationOptions& options, EvaluationResult base)
    : opt_(options), base_(std::move(base)), n_gt_(std::size_t(gt.rows())), gt_(gt) {
  const auto t0 = std::chrono::steady_clock::now();
  base_.n_gt_points = static_cast<std::int64_t>(n_gt_);
  if (n_gt_ > std::numeric_limits<std::uint32_t>::max())  // a cell's count is 32 bits
    throw std::invalid_argument("at most 2^32 - 1 ground-truth points, got " +
                                std::to_string(n_gt_));
  for (double r : opt_.resolutions) {
    Grid g;
    g.r = r;
    const std::vector<std::uint64_t> keys = gt_cell_keys(r);
    g.index.reserve(keys.size() / 8);
    std::uint64_t last = kEmptyVoxelKey;
    std::uint32_t last_pos = 0;
    for (std::uint64_t k : keys) {  // sampling order: runs of equal keys are common
      if (k != last) {
        const auto ins = g.index.insert(k);
        if (ins.second) g.samples.push_back(0);
        last = k;
        last_pos = ins.first;
      }
      ++g.samples[last_pos];
    }
    g.index.shrink_to_fit();  // held for the evaluator's life: not the growth's spare room
    g.samples.shrink_to_fit();
    grids_.push_back(std::move(g));
  }
  base_.timings_s.emplace_back("prepare_gt", seconds_since(t0));
}

EvaluationResult Evaluator::empty_result(std::int64_t n_points) const {
  EvaluationResult res = base_;
  res.resolutions = opt_.resolutions;
  res.taus = opt_.taus;
  res.n_points = n_points;
  const std::size_t nr = opt_.resolutions.size(), nt = opt_.taus.size();
  res.coverage.assign(nr, 0.0);
  res.area_coverage.assign(nr, 0.0);
  res.precision.assign(nr, 0.0);
  res.gt_cells.assign(nr, 0);
  res.cloud_cells.assign(nr, 0);
  res.covered_cells.assign(nr, 0);
  if (!observable_.empty()) {
    res.has_observable = true;
    res.coverage_observable.assign(nr, 0.0);
    res.area_coverage_observable.assign(nr, 0.0);
    res.area_coverage_observable_cells.assign(nr, 0.0);
    res.observable_fraction.assign(nr, 0.0);
    res.observable_cells.assign(nr, 0);
    res.covered_observable_cells.assign(nr, 0);
    res.observable_area_fraction =
        ratio(n_observable_, static_cast<std::int64_t>(observable_.size()));
    for (std::size_t k = 0; k < nr; ++k) {
      res.observable_cells[k] = grids_[k].observable_cells;
      res.observable_fraction[k] =
          ratio(grids_[k].observable_cells, static_cast<std::int64_t>(grids_[k].index.size()));
    }
  }
  res.completeness.assign(nt, 0.0);
  res.accuracy.assign(nt, 0.0);
  res.fscore.assign(nt, 0.0);
  return res;
}

void Evaluator::score_cells(std::size_t k, const std::uint64_t* keys, std::size_t n,
                            EvaluationResult& res) const {
  const Grid& g = grids_[k];
  res.gt_cells[k] = static_cast<std::int64_t>(g.index.size());
  if (n == 0) return;
  // The cloud's distinct cells, found in disjoint parts (a key's part: the top bits of a
  // multiplicative hash; 2 parts from 2 M keys, 4 from 3 M), one hash set per part, the parts in
  // parallel; then each distinct cell that is a GT cell marks it hit (in parallel). The same
  // counts as one set over all keys: on clouds of millions of points the one set's serial
  // insertion, into a table too large for the caches, was most of a progress refresh.
  const int bits = n >= (std::size_t(3) << 20) ? 2 : n >= (std::size_t(2) << 20) ? 1 : 0;
  const std::size_t parts = std::size_t(1) << bits;
  const auto part_of = [bits](std::uint64_t key) {
    return bits ? static_cast<std::size_t>((key * 0x9e3779b97f4a7c15ull) >> (64 - bits)) : 0;
  };
  std::vector<VoxelIndex> unique(parts);  // each part's distinct keys: its keys()
  parallel_chunks(parts, 1, [&](std::size_t pb, std::size_t pe) {
    for (std::size_t part = pb; part < pe; ++part) {
      VoxelIndex& cells = unique[part];
      cells.reserve(n / (4 * parts));
      std::uint64_t last = kEmptyVoxelKey;
      for (const std::uint64_t *it = keys, *end = keys + n; it != end; ++it) {
        const std::uint64_t key = *it;
        if (key == last || part_of(key) != part) continue;
        last = key;
        cells.insert(key);
      }
    }
  });
  std::vector<std::uint8_t> hit(g.index.size(), 0);  // distinct cells: no two writers share one
  std::int64_t n_unique = 0;
  std::atomic<std::int64_t> in_gt{0};
  for (const VoxelIndex& part : unique) {
    const GrowArray<std::uint64_t>& u = part.keys();
    n_unique += static_cast<std::int64_t>(u.size());
    parallel_chunks(u.size(), 1 << 13, [&](std::size_t b, std::size_t e) {
      std::int64_t c = 0;
      for (std::size_t j = b; j < e; ++j) {
        const std::uint32_t at = g.index.find(u[j]);
        if (at == VoxelIndex::kMissing) continue;
        ++c;
        hit[at] = 1;
      }
      in_gt += c;
    });
  }
  const bool obs = !observable_.empty();
  std::atomic<std::int64_t> covered{0}, covered_samples{0}, covered_obs{0}, covered_obs_samples{0},
      covered_obs_cell_samples{0};
  parallel_chunks(g.index.size(), 1 << 13, [&](std::size_t b, std::size_t e) {
    std::int64_t c = 0, s = 0, co = 0, so = 0, sc = 0;
    for (std::size_t j = b; j < e; ++j)
      if (hit[j]) {
        ++c;
        s += g.samples[j];
        if (obs && g.observable_samples[j] > 0) {
          ++co;
          so += g.observable_samples[j];
          sc += g.samples[j];
        }
      }
    covered += c;
    covered_samples += s;
    covered_obs += co;
    covered_obs_samples += so;
    covered_obs_cell_samples += sc;
  });
  set_cell_figures(k,
                   {n_unique, in_gt, covered, covered_samples, covered_obs, covered_obs_samples,
                    covered_obs_cell_samples},
                   res);
}

void Evaluator::set_cell_figures(std::size_t k, const CellTally& t, EvaluationResult& res) const {
  res.gt_cells[k] = static_cast<std::int64_t>(grids_[k].index.size());
  if (!observable_.empty()) {
    res.covered_observable_cells[k] = t.covered_obs;
    res.coverage_observable[k] = ratio(t.covered_obs, grids_[k].observable_cells);
    res.area_coverage_observable[k] = ratio(t.covered_obs_samples, n_observable_);
    res.area_coverage_observable_cells[k] =
        ratio(t.covered_obs_cell_samples, static_cast<std::int64_t>(n_gt_));
  }
  res.cloud_cells[k] = t.cloud_cells;
  res.covered_cells[k] = t.covered;
  res.coverage[k] = ratio(t.covered, res.gt_cells[k]);
  res.area_coverage[k] = ratio(t.covered_samples, static_cast<std::int64_t>(n_gt_));
  res.precision[k] = ratio(t.in_gt, t.cloud_cells);
}

const KdTree& Evaluator::gt_tree() const {
  std::lock_guard<std::mutex> lock(tree_mutex_);
  if (!tree_) {
    tree_ = std::make_unique<KdTree>(redraw() ? sample_again() : gt_);
    gt_ = Points();  // the tree holds them
  }
  return *tree_;
}

Points Evaluator::gt_points() const {
  std::lock_guard<std::mutex> lock(tree_mutex_);
  if (tree_) return tree_->points();
  return redraw() ? sample_again() : gt_;
}

std::vector<std::uint64_t> Evaluator::gt_cell_keys(double r, const Points* drawn) const {
  const Points again = redraw() && !drawn ? sample_again() : Points();
  const Points& held = redraw() ? (drawn ? *drawn : again) : gt_;
  if (tree_)
    return cell_keys(
        n_gt_, [this](std::size_t k) { return tree_->point(Eigen::Index(k)); }, r, "ground truth");
  return cell_keys(
      n_gt_, [&held](std::size_t k) { return Eigen::Vector3d(held.row(Eigen::Index(k))); }, r,
      "ground truth");
}

void Evaluator::set_observable(const std::vector<std::uint8_t>& mask) {
  ++observable_version_;
  if (mask.empty()) {
    observable_.clear();
    n_observable_ = 0;
    for (Grid& g : grids_) {
      g.observable_samples.clear();
      g.observable_cells = 0;
    }
    return;
  }
  if (mask.size() != num_gt_points())
    throw std::invalid_argument("observable mask has " + std::to_string(mask.size()) +
                                " entries for " + std::to_string(num_gt_points()) +
                                " ground-truth samples");
  observable_.assign(mask.begin(), mask.end());
  n_observable_ = 0;
  for (std::uint8_t v : observable_) n_observable_ += v != 0;
  const Points drawn = redraw() ? sample_again() : Points();  // once for every resolution
  for (Grid& g : grids_) {
    const std::vector<std::uint64_t> keys = gt_cell_keys(g.r, &drawn);
    g.observable_samples.assign(g.index.size(), 0);
    for (std::size_t k = 0; k < keys.size(); ++k)
      if (observable_[k]) ++g.observable_samples[g.index.find(keys[k])];
    g.observable_cells = 0;
    for (std::uint32_t c : g.observable_samples) g.observable_cells += c > 0;
  }
}

EvaluationResult Evaluator::evaluate_cells(const PointsRef& cloud) const {
  require_finite(cloud, "cloud");
  const auto t0 = std::chrono::steady_clock::now();
  EvaluationResult res = empty_result(cloud.rows());
  for (std::size_t k = 0; k < opt_.resolutions.size(); ++k) {
    const auto keys = point_cell_keys(cloud, opt_.resolutions[k], "cloud");
    score_cells(k, keys.data(), keys.size(), res);
  }
  res.timings_s.emplace_back("cells", seconds_since(t0));
  return res;
}

EvaluationResult Evaluator::evaluate_cells(const std::vector<const SurfaceCloud*>& clouds) const {
  const auto t0 = std::chrono::steady_clock::now();
  std::size_t n = 0;
  for (const SurfaceCloud* c : clouds) n += c->size();
  EvaluationResult res = empty_result(static_cast<Eigen::Index>(n));
  HugeVector<std::uint64_t> keys(n);  // one scratch array for every resolution
  for (std::size_t k = 0; k < opt_.resolutions.size(); ++k) {
    const double r = opt_.resolutions[k];
    std::size_t offset = 0;
    for (const SurfaceCloud* c : clouds) {
      if (!fill_cell_keys(
              keys.data() + offset, c->size(), [&](std::size_t i) { return c->point(i); }, r))
        throw_too_far("cloud", r);
      offset += c->size();
    }
    score_cells(k, keys.data(), n, res);
  }
  res.timings_s.emplace_back("cells", seconds_since(t0));
  return res;
}

EvaluationResult Evaluator::evaluate(const PointsRef& cloud) const {
  require_finite(cloud, "cloud");
  return score(std::size_t(cloud.rows()), [&cloud](std::size_t i) {
    const auto r = static_cast<Eigen::Index>(i);
    return Eigen::Vector3d(cloud(r, 0), cloud(r, 1), cloud(r, 2));
  });
}

EvaluationResult Evaluator::evaluate(const std::vector<const SurfaceCloud*>& clouds) const {
  // the clouds' points in order, read in place (no stacked copy)
  std::vector<std::size_t> first{0};
  for (const SurfaceCloud* c : clouds) first.push_back(first.back() + c->size());
  return score(first.back(), [&](std::size_t i) {
    const std::size_t c =
        std::size_t(std::upper_bound(first.begin(), first.end(), i) - first.begin()) - 1;
    return clouds[c]->point(i - first[c]);
  });
}

EvaluationResult Evaluator::score(std::size_t n,
                                  const std::function<Eigen::Vector3d(std::size_t)>& point) const {
  using clock = std::chrono::steady_clock;
  EvaluationResult res = empty_result(static_cast<std::int64_t>(n));
  const std::size_t nt = opt_.taus.size();
  const auto n_gt = static_cast<std::int64_t>(n_gt_);

  auto t0 = clock::now();
  for (std::size_t k = 0; k < opt_.resolutions.size(); ++k) {
    const auto keys = cell_keys(n, point, opt_.resolutions[k], "cloud");
    score_cells(k, keys.data(), keys.size(), res);
  }
  const double cells_s = seconds_since(t0);

  // The distances, one part of the cloud at a time: a kd-tree over the part, each part point's
  // distance to the ground truth, and each ground-truth sample's nearest distance so far lowered
  // to the part's nearest. A cloud of up to options.part_points points (by default 4.2 M: every
  // structure of the paper's size) is one part; a 100 m structure's 22 M points are scored in
  // slabs of about that many, and never hold a tree over all of them (1.2 GB).
  struct Sums {
    double total = 0;
    std::vector<std::int64_t> within = {};  // per tau: distances <= tau
    void add(const std::vector<double>& d, const std::vector<double>& taus) {
      for (double x : d) total += x;
      within.resize(taus.size(), 0);
      for (std::size_t k = 0; k < taus.size(); ++k)
        for (double x : d) within[k] += x <= taus[k];
    }
  };
  const auto part_size = static_cast<std::size_t>(opt_.part_points);
  double kdtree_s = 0, nearest_s = 0;
  Sums cloud_to_gt, gt_to_cloud;
  const KdTree* gt = n ? &gt_tree() : nullptr;
  std::vector<double> best2(n ? gt->size() : 0, std::numeric_limits<double>::infinity());
  // the parts: the whole cloud, or slabs of it along its longest axis (a sample far from a slab
  // is not searched there), each after an upper bound from every 32nd point (a subset: no nearer
  // than the cloud's nearest), so that a sample whose slab comes late has a near bound at once
  const std::vector<std::uint8_t> slab_of =
      n > part_size ? cloud_slabs(n, point, part_size) : std::vector<std::uint8_t>{};
  const std::size_t parts =
      slab_of.empty() ? (n ? 1 : 0)
                      : std::size_t(*std::max_element(slab_of.begin(), slab_of.end())) + 1;
  if (parts > 1) {
    t0 = clock::now();
    const KdTree every((n + 31) / 32, [&](std::size_t i) { return point(i * 32); });
    kdtree_s += seconds_since(t0);
    t0 = clock::now();
    tree_nearest_lower(every, *gt, best2);
    nearest_s += seconds_since(t0);
  }
  for (std::size_t s = 0; s < parts; ++s) {
    t0 = clock::now();
    std::vector<std::uint32_t> in;  // the slab's points
    for (std::size_t i = 0; i < slab_of.size(); ++i)
      if (slab_of[i] == s) in.push_back(std::uint32_t(i));
    const KdTree part = slab_of.empty()
                            ? KdTree(n, point)
                            : KdTree(in.size(), [&](std::size_t i) { return point(in[i]); });
    kdtree_s += seconds_since(t0);
    t0 = clock::now();
    cloud_to_gt.add(tree_nearest(*gt, part), opt_.taus);  // each part in its tree order
    tree_nearest_lower(part, *gt, best2);                 // GT samples in GT tree order
    nearest_s += seconds_since(t0);
  }
  res.timings_s.emplace_back("cloud_kdtree", kdtree_s);
  res.timings_s.emplace_back("cells", cells_s);
  if (n == 0) return res;
  t0 = clock::now();
  for (double& d : best2) d = std::sqrt(d);
  gt_to_cloud.add(best2, opt_.taus);
  res.timings_s.emplace_back("nearest", nearest_s + seconds_since(t0));

  res.mean_cloud_to_gt = cloud_to_gt.total / static_cast<double>(n);
  res.mean_gt_to_cloud = gt_to_cloud.total / static_cast<double>(n_gt);
  res.chamfer = 0.5 * (res.mean_cloud_to_gt + res.mean_gt_to_cloud);
  res.has_chamfer = true;
  for (std::size_t k = 0; k < nt; ++k) {
    const double P = ratio(cloud_to_gt.within[k], static_cast<std::int64_t>(n)),
                 R = ratio(gt_to_cloud.within[k], n_gt);
    res.accuracy[k] = P;
    res.completeness[k] = R;
    res.fscore[k] = (P + R) > 0 ? 2 * P * R / (P + R) : 0.0;
  }
  return res;
}

EvaluationResult evaluate(const Mesh& gt, const PointsRef& cloud,
                          const EvaluationOptions& options) {
  require_finite(cloud, "cloud");
  return Evaluator(gt, options).evaluate(cloud);
}

EvaluationResult evaluate_points(const PointsRef& gt, const PointsRef& cloud,
                                 const EvaluationOptions& options) {
  require_finite(cloud, "cloud");
  return Evaluator(gt, options).evaluate(cloud);
}

std::vector<std::uint64_t> point_cell_keys(const PointsRef& pts, double r, const char* what) {
  if (!(std::isfinite(r) && r > 0))
    throw std::invalid_argument(std::string("cell size must be a positive number of metres, got ") +
                                fmt(r));
  return cell_keys(
      std::size_t(pts.rows()),
      [&](std::size_t k) { return Eigen::Vector3d(pts.row(Eigen::Index(k)).transpose()); }, r,
      what);
}

}  // namespace nbv

// ---------------------------------------------------------------------------- CoverageTracker

namespace nbv {

CoverageTracker::CoverageTracker(const Evaluator& evaluator) : ev_(evaluator) { reset(); }

void CoverageTracker::reset() {
  clouds_.clear();
  cells_.clear();
  cells_.resize(ev_.opt_.resolutions.size());
  observable_version_ = ev_.observable_version_;
}

std::size_t CoverageTracker::bytes() const {
  std::size_t b = 0;
  for (const Cloud& c : clouds_) {
    b += c.count.capacity() * sizeof(std::uint32_t);
    for (const auto& cell : c.cell) b += cell.capacity() * sizeof(std::uint32_t);
  }
  for (const Cells& c : cells_)
    b += c.index.bytes() + (c.n.capacity() + c.gt.capacity()) * sizeof(std::uint32_t);
  return b;
}

std::uint32_t CoverageTracker::cell_of(std::size_t k, std::uint64_t key) {
  Cells& c = cells_[k];
  const auto ins = c.index.insert(key);
  if (ins.second) {
    c.n.push_back(0);
    c.gt.push_back(ev_.grids_[k].index.find(key));
  }
  return ins.first;
}

void CoverageTracker::add_point(std::size_t k, std::uint32_t id) {
  Cells& c = cells_[k];
  if (c.n[id]++ != 0) return;
  ++c.occupied;
  const std::uint32_t g = c.gt[id];
  if (g == VoxelIndex::kMissing) return;
  const Evaluator::Grid& grid = ev_.grids_[k];
  ++c.covered;
  c.covered_samples += grid.samples[g];
  if (!grid.observable_samples.empty() && grid.observable_samples[g] > 0) {
    ++c.covered_obs;
    c.covered_obs_samples += grid.observable_samples[g];
    c.covered_obs_cell_samples += grid.samples[g];
  }
}

void CoverageTracker::remove_point(std::size_t k, std::uint32_t id) {
  Cells& c = cells_[k];
  if (--c.n[id] != 0) return;
  --c.occupied;
  const std::uint32_t g = c.gt[id];
  if (g == VoxelIndex::kMissing) return;
  const Evaluator::Grid& grid = ev_.grids_[k];
  --c.covered;
  c.covered_samples -= grid.samples[g];
  if (!grid.observable_samples.empty() && grid.observable_samples[g] > 0) {
    --c.covered_obs;
    c.covered_obs_samples -= grid.observable_samples[g];
    c.covered_obs_cell_samples -= grid.samples[g];
  }
}

void CoverageTracker::count_observable(std::size_t k) {
  Cells& c = cells_[k];
  const Evaluator::Grid& grid = ev_.grids_[k];
  c.covered_obs = c.covered_obs_samples = c.covered_obs_cell_samples = 0;
  if (grid.observable_samples.empty()) return;
  for (std::size_t id = 0; id < c.index.size(); ++id)
    if (c.n[id] > 0 && c.gt[id] != VoxelIndex::kMissing && grid.observable_samples[c.gt[id]] > 0) {
      ++c.covered_obs;
      c.covered_obs_samples += grid.observable_samples[c.gt[id]];
      c.covered_obs_cell_samples += grid.samples[c.gt[id]];
    }
}

EvaluationResult CoverageTracker::update(const std::vector<const SurfaceCloud*>& clouds) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::vector<double>& res_m = ev_.opt_.resolutions;
  const std::size_t nr = res_m.size();
  const bool same_list = clouds.size() == clouds_.size();  // else every count starts again
  // Pass 1 (parallel, nothing modified): per cloud, the points that are new or whose voxel
  // count changed and whose cell changed at some resolution, with their keys at every
  // resolution, in blocks of a fixed size so that they are applied in point order.
  constexpr std::size_t kBlock = std::size_t(1) << 14;
  struct Block {
    std::vector<std::uint32_t> point;
    std::vector<std::uint64_t> key;  // nr per point
  };
  std::vector<std::vector<Block>> changes(clouds.size());
  std::vector<std::atomic<bool>> too_far(nr);
  for (auto& f : too_far) f = false;
  std::vector<double> inv(nr);
  for (std::size_t k = 0; k < nr; ++k) inv[k] = 1.0 / res_m[k];
  for (std::size_t c = 0; c < clouds.size(); ++c) {
    const SurfaceCloud& cloud = *clouds[c];
    static const Cloud kNew;
    const Cloud& seen = same_list ? clouds_[c] : kNew;
    const bool same = same_list && seen.stamp == cloud.stamp();
    const std::size_t n = cloud.size(), m = same ? seen.count.size() : 0;
    const GrowArray<std::uint32_t>& counts = cloud.voxel_counts();
    std::vector<Block>& blocks = changes[c];
    blocks.resize((n + kBlock - 1) / kBlock);
    parallel_chunks(blocks.size(), 1, [&](std::size_t bb, std::size_t be) {
      std::vector<std::uint64_t> keys(nr);
      for (std::size_t b = bb; b < be; ++b) {
        Block& out = blocks[b];
        for (std::size_t i = b * kBlock, e = std::min(n, i + kBlock); i < e; ++i) {
          if (i < m && counts[i] == seen.count[i]) continue;
          const Eigen::Vector3d p = cloud.point(i);
          bool moved = i >= m;
          for (std::size_t k = 0; k < nr; ++k) {
            keys[k] = try_cell_key(p.x(), p.y(), p.z(), res_m[k], inv[k]);
            if (keys[k] == kEmptyVoxelKey) too_far[k] = true;
            if (!moved && keys[k] != cells_[k].index.key(seen.cell[k][i])) moved = true;
          }
          if (!moved) continue;
          out.point.push_back(static_cast<std::uint32_t>(i));
          out.key.insert(out.key.end(), keys.begin(), keys.end());
        }
      }
    });
  }
  for (std::size_t k = 0; k < nr; ++k)
    if (too_far[k]) throw_too_far("cloud", res_m[k]);
  const double scan_s = seconds_since(t0);

  // Pass 2: a cloud cleared or replaced gives its points back; then every change moves its point
  // between cells. Each resolution's cells are apart: the resolutions in parallel.
  if (!same_list) {
    reset();
    clouds_.resize(clouds.size());
  }
  std::size_t n_points = 0;
  std::vector<std::size_t> before(clouds.size());  // points seen before this call, per cloud
  for (std::size_t c = 0; c < clouds.size(); ++c) {
    const SurfaceCloud& cloud = *clouds[c];
    Cloud& seen = clouds_[c];
    n_points += cloud.size();
    if (seen.stamp != cloud.stamp()) {
      for (std::size_t k = 0; k < seen.cell.size(); ++k)
        for (std::uint32_t id : seen.cell[k]) remove_point(k, id);
      seen = Cloud{};
      seen.stamp = cloud.stamp();
      seen.cell.resize(nr);
    }
    before[c] = seen.count.size();
    seen.count.assign(cloud.voxel_counts().begin(), cloud.voxel_counts().end());
  }
  parallel_chunks(nr, 1, [&](std::size_t kb, std::size_t ke) {
    for (std::size_t k = kb; k < ke; ++k)
      for (std::size_t c = 0; c < clouds.size(); ++c) {
        GrowArray<std::uint32_t>& cell = clouds_[c].cell[k];
        cell.resize(clouds[c]->size());
        for (const Block& blk : changes[c])
          for (std::size_t j = 0; j < blk.point.size(); ++j) {
            const std::size_t i = blk.point[j];
            const std::uint64_t key = blk.key[j * nr + k];
            if (i < before[c]) {
              if (cells_[k].index.key(cell[i]) == key) continue;
              remove_point(k, cell[i]);
            }
            cell[i] = cell_of(k, key);
            add_point(k, cell[i]);
          }
      }
  });
  if (observable_version_ != ev_.observable_version_) {
    for (std::size_t k = 0; k < nr; ++k) count_observable(k);
    observable_version_ = ev_.observable_version_;
  }

  EvaluationResult res = ev_.empty_result(static_cast<std::int64_t>(n_points));
  for (std::size_t k = 0; k < nr; ++k) {
    const Cells& c = cells_[k];  // a covered cell is a cloud cell found in the ground truth
    ev_.set_cell_figures(k,
                         {c.occupied, c.covered, c.covered, c.covered_samples, c.covered_obs,
                          c.covered_obs_samples, c.covered_obs_cell_samples},
                         res);
  }
  res.timings_s.emplace_back("cells", seconds_since(t0));
  res.timings_s.emplace_back("scan", scan_s);  // of which pass 1
  return res;
}

}  // namespace nbv
