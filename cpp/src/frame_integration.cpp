#include "nbv/frame_integration.hpp"

#include "nbv/parallel.hpp"

#include <tbb/parallel_invoke.h>

#include <algorithm>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace nbv {

FrameIntegration integrate_frame(OccupancyMap& map, SurfaceCloud& cloud,
                                 SurfaceObservations& surface, const Scan& scan, double max_range,
                                 const DepthCamera* next_camera, const Pose* next_pose) {
  // Checked first, once: what any of the three would refuse (the map's origin and points, which
  // its update, run beside the others, does not read again; the cloud's keys, which also check
  // the hits; the observations need finite hits and origin), and the next frame's pose as the
  // camera's scan checks it.
  map.check_scan(scan.origin, scan.hits, scan.free_ends, max_range);
  if (!surface.matches(map))  // (its hits outside the other grid were dropped without a word)
    throw std::invalid_argument("surface observations were made for another map's grid");
  if (bool(next_camera) != bool(next_pose))
    throw std::invalid_argument("integrate_frame: a next frame needs both a camera and a pose");
  Eigen::Isometry3d next_T = Eigen::Isometry3d::Identity();
  if (next_camera) {
    require_pitch(next_pose->pitch, "next camera view");
    next_T = gimbal_sensor_transform(*next_pose, next_camera->options().mount);
    check_sensor_pose(next_T);
  }
  const std::vector<std::uint64_t> keys = cloud.voxel_keys(scan.hits);
  FrameIntegration out;
  const auto integrate_map = [&] { out.map = map.integrate_checked(scan, max_range); };
  const auto add_points = [&] {
    out.cloud_voxels = cloud.add_keyed(scan.hits, keys);
    out.new_cells = surface.add_scan(scan.origin, scan.hits, scan.sparse_hits);
  };
  core_arena()->execute([&] {
    if (next_camera)
      tbb::parallel_invoke(integrate_map, add_points,
                           [&] { out.next_scan = next_camera->scan(next_T); });
    else
      tbb::parallel_invoke(integrate_map, add_points);
  });
  return out;
}

Scan refine_frame(const DepthCamera& camera, const Scan& coarse, const Pose& pose,
                  const SurfaceObservations& surface, double cone_deg) {
  const int W = camera.options().width, H = camera.options().height;
  const int w = int(coarse.depth.cols()), h = int(coarse.depth.rows());
  if (w < 1 || h < 1 || w > W || h > H)
    throw std::invalid_argument("refine_frame: a coarse frame of " + std::to_string(w) + " x " +
                                std::to_string(h) + " pixels is not coarser than the " +
                                std::to_string(W) + " x " + std::to_string(H) + " camera's");
  require_pitch(pose.pitch, "refined frame");
  const Eigen::Isometry3d T = gimbal_sensor_transform(pose, camera.options().mount);
  check_sensor_pose(T);
  if (coarse.hit_rays.size() != coarse.hits.rows() ||
      coarse.free_rays.size() != coarse.free_ends.rows())
    throw std::invalid_argument("refine_frame: the coarse frame's rays do not match its points");
  const auto inside = [&](const Eigen::VectorXi& rays) {
    return rays.size() == 0 || (rays.minCoeff() >= 0 && rays.maxCoeff() < w * h);
  };
  if (!inside(coarse.hit_rays) || !inside(coarse.free_rays))
    throw std::invalid_argument("refine_frame: a coarse ray's pixel is outside its image");
  // coarse pixel (uc, vc) spans the full-resolution pixels u in [col0[uc], col0[uc + 1]) and v
  // in [row0[vc], row0[vc + 1]): those whose left (top) edges lie within its extent
  std::vector<int> col0(std::size_t(w) + 1), row0(std::size_t(h) + 1);
  for (int c = 0; c <= w; ++c) col0[std::size_t(c)] = int((std::int64_t(c) * W + w - 1) / w);
  for (int c = 0; c <= h; ++c) row0[std::size_t(c)] = int((std::int64_t(c) * H + h - 1) / h);
  // the coarse pixels refined: each novel hit's (one a denser frame could add to) and its 8
  // neighbours' (a new surface's edges)
  const std::vector<std::uint8_t> novel =
      surface.novel_mask(coarse.origin, coarse.hits, cone_deg, /*whole_face=*/true);
  std::vector<std::uint8_t> refine(std::size_t(w) * h, 0);
  for (Eigen::Index r = 0; r < coarse.hits.rows(); ++r) {
    if (!novel[std::size_t(r)]) continue;
    const int uc = coarse.hit_rays[r] % w, vc = coarse.hit_rays[r] / w;
    for (int v = std::max(0, vc - 1); v <= std::min(h - 1, vc + 1); ++v)
      for (int u = std::max(0, uc - 1); u <= std::min(w - 1, uc + 1); ++u)
        refine[std::size_t(v) * w + u] = 1;
  }
  // their blocks' pixels, block after block in the coarse image's order (coherent packets)
  std::vector<int> pixels;
  for (int vc = 0; vc < h; ++vc)
    for (int uc = 0; uc < w; ++uc) {
      if (!refine[std::size_t(vc) * w + uc]) continue;
      for (int v = row0[std::size_t(vc)]; v < row0[std::size_t(vc) + 1]; ++v)
        for (int u = col0[std::size_t(uc)]; u < col0[std::size_t(uc) + 1]; ++u)
          pixels.push_back(v * W + u);
    }
  const Scan fine = camera.scan_pixels(
      T, Eigen::Map<const Eigen::VectorXi>(pixels.data(), Eigen::Index(pixels.size())));
  // the coarse rays kept (their pixel not refined), then the refined pixels' rays
  const auto keep = [&](const Points& pts, const Eigen::VectorXi& rays, const Points& more,
                        const Eigen::VectorXi& more_rays, Points& out_pts,
                        Eigen::VectorXi& out_rays) {
    Eigen::Index kept = 0;
    for (Eigen::Index r = 0; r < rays.size(); ++r) kept += !refine[std::size_t(rays[r])];
    out_pts.resize(kept + more.rows(), 3);
    out_rays.resize(out_pts.rows());
    Eigen::Index i = 0;
    for (Eigen::Index r = 0; r < rays.size(); ++r) {
      if (refine[std::size_t(rays[r])]) continue;
      out_pts.row(i) = pts.row(r);
      out_rays[i++] = row0[std::size_t(rays[r] / w)] * W + col0[std::size_t(rays[r] % w)];
    }
    out_pts.bottomRows(more.rows()) = more;
    out_rays.tail(more.rows()) = more_rays;
  };
  Scan out;
  out.origin = coarse.origin;
  keep(coarse.hits, coarse.hit_rays, fine.hits, fine.hit_rays, out.hits, out.hit_rays);
  out.sparse_hits = out.hits.rows() - fine.hits.rows();
  keep(coarse.free_ends, coarse.free_rays, fine.free_ends, fine.free_rays, out.free_ends,
       out.free_rays);
  out.depth.resize(H, W);
  std::vector<int> column(static_cast<std::size_t>(W));  // each pixel column's coarse column
  for (int u = 0; u < W; ++u) column[std::size_t(u)] = int(std::int64_t(u) * w / W);
  for (int v = 0; v < H; ++v) {
    const double* from = coarse.depth.data() + std::int64_t(v) * h / H * w;
    double* to = out.depth.data() + std::int64_t(v) * W;
    for (int u = 0; u < W; ++u) to[u] = from[column[std::size_t(u)]];
  }
  for (std::size_t i = 0; i < pixels.size(); ++i)
    out.depth(pixels[i] / W, pixels[i] % W) = fine.depth(0, Eigen::Index(i));
  return out;
}

}  // namespace nbv
