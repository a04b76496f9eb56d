// A camera frame integrated into everything a mission keeps of it at once: the occupancy map,
// the camera cloud and the camera observations, the map's update beside the other two.
#pragma once

#include "nbv/occupancy_map.hpp"
#include "nbv/point_cloud.hpp"
#include "nbv/sensors.hpp"
#include "nbv/surface_observations.hpp"

#include <cstddef>
#include <limits>
#include <optional>

namespace nbv {

/// What integrate_frame changed.
struct FrameIntegration {
  IntegrationStats map;           ///< OccupancyMap::integrate's statistics
  std::size_t cloud_voxels = 0;   ///< voxels the camera cloud gained (SurfaceCloud::add)
  std::size_t new_cells = 0;      ///< cells the camera saw first (SurfaceObservations::add_scan)
  std::optional<Scan> next_scan;  ///< the next frame, where one was asked for
};

/// map.integrate(scan, max_range), cloud.add(scan.hits) and surface.add_scan(scan.origin,
/// scan.hits), with the same results, the map's update running beside the cloud's and the
/// observations' (each of the three is parallel on its own; side by side their serial parts
/// overlap). Everything that could refuse the frame is checked first, so a refused frame changes
/// nothing: throws std::invalid_argument for a non-finite or unaddressable origin, a non-finite
/// point, a hit beyond the cloud's range, or a next pose next_camera cannot take. The caller
/// holds the objects' access locks.
///
/// With next_camera and next_pose, the next frame (next_camera->scan_pose(*next_pose), which
/// reads none of the three) is taken meanwhile, as a third task, and returned in next_scan: a
/// flight whose next pose is known casts its next frame while this one is integrated.
FrameIntegration integrate_frame(OccupancyMap& map, SurfaceCloud& cloud,
                                 SurfaceObservations& surface, const Scan& scan,
                                 double max_range = std::numeric_limits<double>::infinity(),
                                 const DepthCamera* next_camera = nullptr,
                                 const Pose* next_pose = nullptr);

/// A frame taken at 1/N of the camera's pixels on each axis (`coarse`, from a camera of the same
/// field of view, range and mount at W/N x H/N pixels, at `pose`), refined to the full
/// resolution where it could see something new: each coarse hit that a denser frame could add to
/// the camera observations with (SurfaceObservations::novel_mask with cone_deg and whole_face: a
/// side unseen, a square unmarked, or a cell none of whose projections along the axes has all its
/// squares marked) has the block of the image its coarse pixel spans, and the 8
/// neighbouring blocks (a new surface's edges), cast again pixel by pixel with `camera`
/// (DepthCamera::scan_pixels);
/// their pixels replace the coarse rays. Where the frame adds nothing, its coarse rays stand: the
/// map is cleared and known surface resampled as by the coarse frame. Returns the frame as one
/// Scan: the coarse hits kept then the refined pixels' hits, the coarse free ends kept then the
/// refined ones, hit_rays and free_rays as full-resolution pixels (a coarse ray: its block's
/// first pixel) and depth (H, W), each pixel its own depth where refined, its block's coarse
/// depth elsewhere. Reads the observations only. Throws std::invalid_argument for a coarse frame
/// finer than the camera's or whose rays do not match its points, or a pose the camera cannot
/// take.
Scan refine_frame(const DepthCamera& camera, const Scan& coarse, const Pose& pose,
                  const SurfaceObservations& surface, double cone_deg);

}  // namespace nbv
