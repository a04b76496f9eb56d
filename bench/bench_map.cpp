// Map integration speed: nbv::OccupancyMap::integrate (fast path) against plain OctoMap on the
// same camera frames in the same run, the agreement of the resulting maps, and total_entropy().
//
// Build and run (from the repository root):
//   cmake -S . -B build/bench -G Ninja -DNBV_BUILD_BENCH=ON -DNBV_BUILD_PYTHON=OFF
//   cmake --build build/bench --target bench_map && build/bench/bench_map [MESH] [--repeat N]
// MESH defaults to meshes/airliner.obj. Frames: a 640 x 480 camera (0.5-8 m) at 8 poses on a
// ring of radius 10 m around the mesh centre at z = 4 m, facing it; map 0.2 m over the paper's
// 40 x 40 x 10 m workspace (2,000,000 cells).
//
// "plain" is what octomap::OcTree::insertPointCloud(hits, origin) does, with the no-hit rays
// added to the same computeUpdate key sets (their cells up to and including the ray end free) -
// on a bare octomap::OcTree, no mirror. "exact" is OccupancyMap::integrate_exact (the same through
// OctoMap plus the mirror). "fast" is OccupancyMap::integrate. Agreement: the share of cells
// touched by either map (state not unknown in one of them) whose free/occupied/unknown state is
// the same in the fast map and the exact map, after each frame, cumulative over the sequence.
#include "nbv/mesh.hpp"
#include "nbv/occupancy_map.hpp"
#include "nbv/parallel.hpp"
#include "nbv/sensors.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

namespace {

using Clock = std::chrono::steady_clock;

double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty()
             ? 0.0
             : (v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]));
}

/// octomap::OcTree::insertPointCloud(hits, origin) with the free rays in the same key sets.
void plain_insert(octomap::OcTree& tree, const nbv::Scan& s) {
  const octomap::point3d o(float(s.origin.x()), float(s.origin.y()), float(s.origin.z()));
  octomap::Pointcloud cloud;
  cloud.reserve(std::size_t(s.hits.rows()));
  for (Eigen::Index r = 0; r < s.hits.rows(); ++r)
    cloud.push_back(float(s.hits(r, 0)), float(s.hits(r, 1)), float(s.hits(r, 2)));
  octomap::KeySet free_cells, occupied_cells;
  tree.computeUpdate(cloud, o, free_cells, occupied_cells, -1.0);
  octomap::KeyRay ray;
  for (Eigen::Index r = 0; r < s.free_ends.rows(); ++r) {
    const octomap::point3d p(float(s.free_ends(r, 0)), float(s.free_ends(r, 1)),
                             float(s.free_ends(r, 2)));
    if (tree.computeRayKeys(o, p, ray)) free_cells.insert(ray.begin(), ray.end());
    octomap::OcTreeKey k;
    if (tree.coordToKeyChecked(p, k)) free_cells.insert(k);
  }
  for (auto it = free_cells.begin(); it != free_cells.end();)
    it = occupied_cells.count(*it) ? free_cells.erase(it) : std::next(it);
  for (const auto& k : free_cells) tree.updateNode(k, false, false);
  for (const auto& k : occupied_cells) tree.updateNode(k, true, false);
}

/// Share of cells touched by either map whose state agrees.
double agreement(const nbv::OccupancyMap& a, const nbv::OccupancyMap& b,
                 std::int64_t* touched_out) {
  std::int64_t touched = 0, same = 0;
  for (std::size_t id = 0; id < a.grid().layout().storage_size(); ++id) {
    const auto i = std::int64_t(id);
    const auto sa = a.grid().state(i), sb = b.grid().state(i);
    if (sa == nbv::CellState::Unknown && sb == nbv::CellState::Unknown) continue;
    ++touched;
    same += sa == sb;
  }
  if (touched_out) *touched_out = touched;
  return touched ? double(same) / double(touched) : 1.0;
}

}  // namespace

int main(int argc, char** argv) {
  std::string mesh_path = "meshes/airliner.obj";
  int repeat = 5;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--repeat" && i + 1 < argc)
      repeat = std::max(1, std::atoi(argv[++i]));
    else if (a == "-h" || a == "--help") {
      std::printf("usage: bench_map [MESH] [--repeat N]\n");
      return 0;
    } else
      mesh_path = a;
  }
  const nbv::Mesh mesh = nbv::load_mesh(mesh_path);
  auto scene = std::make_shared<nbv::RaycastScene>(mesh);
  nbv::DepthCamera cam(scene);
  const Eigen::Vector3d lo = mesh.vertices.colwise().minCoeff(),
                        hi = mesh.vertices.colwise().maxCoeff();
  const Eigen::Vector3d c = 0.5 * (lo + hi);
  std::vector<nbv::Scan> scans;
  for (int k = 0; k < 8; ++k) {
    const double th = k * M_PI / 4;
    scans.push_back(cam.scan_pose(
        nbv::Pose{c.x() + 10 * std::cos(th), c.y() + 10 * std::sin(th), 4.0, th + M_PI}));
  }
  const double res = 0.2;
  const Eigen::Vector3d bmin(-20, -20, 0), bmax(20, 20, 10);
  std::printf(
      "mesh %s: %ld triangles; %zu frames %dx%d, map %.2f m over (-20,-20,0)-(20,20,10); %d "
      "threads\n",
      mesh_path.c_str(), long(mesh.faces.rows()), scans.size(), cam.options().width,
      cam.options().height, res, nbv::get_num_threads());
  std::printf("times: median of %d runs of the whole sequence (each run on fresh maps)\n\n",
              repeat);

  const std::size_t nf = scans.size();
  std::vector<std::vector<double>> t_fast(nf), t_exact(nf), t_plain(nf), t_plain_hits(nf),
      t_fast1(nf);
  std::vector<double> agree(nf, 0.0), agree_single(nf, 0.0);
  std::vector<std::int64_t> touched(nf, 0);
  std::vector<std::size_t> traced(nf, 0);
  double te_ns = 0, tre_ms = 0;
  for (int rep = 0; rep < repeat; ++rep) {
    nbv::OccupancyMap fast(res, bmin, bmax), exact(res, bmin, bmax);
    octomap::OcTree plain(res), plain_hits(res);
    for (octomap::OcTree* t : {&plain, &plain_hits}) {  // the map's sensor model (octomap_server's)
      t->setProbHit(0.7);
      t->setProbMiss(0.4);
      t->setClampingThresMin(0.12);
      t->setClampingThresMax(0.97);
      t->setOccupancyThres(0.6);
    }
    for (std::size_t f = 0; f < nf; ++f) {
      const nbv::Scan& s = scans[f];
      auto t0 = Clock::now();
      const auto st = fast.integrate(s);
      t_fast[f].push_back(ms_since(t0));
      traced[f] = st.traced_rays;
      t0 = Clock::now();
      exact.integrate_exact(s.origin, s.hits, s.free_ends);
      t_exact[f].push_back(ms_since(t0));
      t0 = Clock::now();
      plain_insert(plain, s);
      t_plain[f].push_back(ms_since(t0));
      octomap::Pointcloud cloud;
      for (Eigen::Index r = 0; r < s.hits.rows(); ++r)
        cloud.push_back(float(s.hits(r, 0)), float(s.hits(r, 1)), float(s.hits(r, 2)));
      t0 = Clock::now();
      plain_hits.insertPointCloud(
          cloud, octomap::point3d(float(s.origin.x()), float(s.origin.y()), float(s.origin.z())));
      t_plain_hits[f].push_back(ms_since(t0));
      if (rep == 0) {
        agree[f] = agreement(fast, exact, &touched[f]);
        nbv::OccupancyMap f1(res, bmin, bmax), e1(res, bmin, bmax);
        f1.integrate(s);
        e1.integrate_exact(s.origin, s.hits, s.free_ends);
        agree_single[f] = agreement(f1, e1, nullptr);
      }
    }
    // total entropy: the incremental sum (O(1)) and a full recompute for reference
    const int n_te = 100000;
    volatile double sink = 0;
    auto t0 = Clock::now();
    for (int i = 0; i < n_te; ++i) sink = sink + fast.total_entropy();
    te_ns = ms_since(t0) * 1e6 / n_te;
    t0 = Clock::now();
    sink = sink + fast.recompute_total_entropy();
    tre_ms = ms_since(t0);
    if (rep == 0 &&
        (fast.total_entropy() != fast.recompute_total_entropy() || fast.verify_mirror() != 0)) {
      std::printf("ERROR: incremental totals or mirror out of sync\n");
      return 1;
    }
  }
  {  // single thread, fast path only
    nbv::set_num_threads(1);
    for (int rep = 0; rep < repeat; ++rep) {
      nbv::OccupancyMap fast(res, bmin, bmax);
      for (std::size_t f = 0; f < nf; ++f) {
        auto t0 = Clock::now();
        fast.integrate(scans[f]);
        t_fast1[f].push_back(ms_since(t0));
      }
    }
    nbv::set_num_threads(0);
  }

  std::printf("%5s %7s %7s %7s | %8s %8s %8s %8s %8s | %6s | %9s %9s %8s\n", "frame", "hits",
              "free", "traced", "fast ms", "fast 1t", "exact ms", "plain ms", "pc-hits", "ratio",
              "agree cum", "agree 1f", "touched");
  std::vector<double> mf, mp, mx, ratios, bf, bp;
  double min_agree = 1.0, min_agree1 = 1.0;
  for (std::size_t f = 0; f < nf; ++f) {
    const double a = median(t_fast[f]), a1 = median(t_fast1[f]), x = median(t_exact[f]),
                 p = median(t_plain[f]), ph = median(t_plain_hits[f]);
    mf.push_back(a);
    mp.push_back(p);
    bf.push_back(*std::min_element(t_fast[f].begin(), t_fast[f].end()));
    bp.push_back(*std::min_element(t_plain[f].begin(), t_plain[f].end()));
    mx.push_back(x);
    ratios.push_back(p / a);
    min_agree = std::min(min_agree, agree[f]);
    min_agree1 = std::min(min_agree1, agree_single[f]);
    std::printf(
        "%5zu %7ld %7ld %7zu | %8.2f %8.2f %8.1f %8.1f %8.1f | %5.1fx | %8.3f%% %8.3f%% %8ld\n", f,
        long(scans[f].hits.rows()), long(scans[f].free_ends.rows()), traced[f], a, a1, x, p, ph,
        p / a, 100 * agree[f], 100 * agree_single[f], long(touched[f]));
  }
  std::printf(
      "\nmedian over frames: fast %.2f ms, plain %.1f ms (ratio %.1fx; worst frame %.1fx), exact "
      "%.1f ms\n",
      median(mf), median(mp), median(mp) / median(mf),
      *std::min_element(ratios.begin(), ratios.end()), median(mx));
  std::printf("best run per frame, median over frames: fast %.2f ms, plain %.1f ms (ratio %.1fx)\n",
              median(bf), median(bp), median(bp) / median(bf));
  std::printf(
      "agreement with exact (insertPointCloud semantics): worst %.3f%% cumulative, %.3f%% single "
      "frame\n",
      100 * min_agree, 100 * min_agree1);
  std::printf(
      "total_entropy(): %.1f ns (incremental); recompute_total_entropy(): %.2f ms (full sweep)\n",
      te_ns, tre_ms);
  return 0;
}
