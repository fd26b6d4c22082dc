#pragma once
// KITTI tracking labels (label_02/NNNN.txt): one object per line,
//   frame track_id type truncated occluded alpha left top right bottom h w l x y z ry
// 2-D boxes are in image_02 pixels; the 3-D box is in rectified camera 0 coordinates with
// (x, y, z) the centre of the box's bottom face, h/w/l its height/width/length in metres and ry
// the rotation about the camera y axis (0 = object facing along camera x).
#include <Eigen/Core>
#include <istream>
#include <map>
#include <string>
#include <vector>

#include "slam/common/pose.h"

namespace pcr {

struct TrackedObject {
  int frame = 0;
  int track_id = -1;  // -1 for DontCare regions
  std::string type;   // Car, Van, Truck, Pedestrian, Person_sitting, Cyclist, Tram, Misc, DontCare
  double truncated = 0;                                      // 0..1 (tracking labels: 0, 1, 2)
  int occluded = 0;                                          // 0 visible .. 3 unknown
  double alpha_rad = 0;                                      // observation angle
  Eigen::Vector4d bbox_px = Eigen::Vector4d::Zero();         // left, top, right, bottom (image_02)
  Eigen::Vector3d size_m = Eigen::Vector3d::Zero();          // height, width, length
  Eigen::Vector3d bottom_in_cam0 = Eigen::Vector3d::Zero();  // x, y, z of the bottom centre
  double ry_rad = 0;                                         // rotation about cam0 y

  bool IsDontCare() const { return type == "DontCare"; }
  // Centre of the 3-D box in rectified camera 0 coordinates (y points down).
  Eigen::Vector3d CenterInCam0() const {
    return bottom_in_cam0 - Eigen::Vector3d(0, size_m.x() / 2, 0);
  }
};

struct TrackingLabels {
  // frames[f] holds the objects of frame f (DontCare rows dropped unless asked for).
  std::vector<std::vector<TrackedObject>> frames;
  // The observations of one track in frame order.
  std::vector<TrackedObject> Track(int track_id) const;
  // Track ids present, ascending.
  std::vector<int> TrackIds() const;
};

// Throws InputError naming the line for a wrong field count, a non-numeric or non-finite value,
// a negative frame, a negative track id on a non-DontCare row, negative box sizes or a frame
// number that decreases.
TrackingLabels ReadTrackingLabels(const std::string& path, bool keep_dont_care = false);
TrackingLabels ReadTrackingLabels(std::istream& in, const std::string& name,
                                  bool keep_dont_care = false);

// The 8 corners of the 3-D box in rectified camera 0 coordinates: 0-3 on the bottom face, 4-7 on
// the top face (corner k + 4 above corner k).
std::vector<Eigen::Vector3d> BoxCorners(const TrackedObject& object);

struct ProjectedBox {
  std::vector<Eigen::Vector2d> polygon;  // convex outline, clipped to the image; empty if unseen
  Eigen::Vector4d rect_px = Eigen::Vector4d::Zero();  // left, top, right, bottom of the polygon
  bool empty() const { return polygon.empty(); }
};

// Projects the 3-D box into a rectified camera with projection matrix P (3x4, e.g. P_rect_00 or
// P_rect_02, mapping rectified cam0 coordinates to pixels). Parts closer than near_m to the
// camera plane are cut away; the outline is clipped to [0, width] x [0, height]. Empty when the
// box is behind the camera or outside the image.
ProjectedBox ProjectBox(const TrackedObject& object, const Eigen::Matrix<double, 3, 4>& p,
                        int width_px, int height_px, double near_m = 0.1);

struct TrackMotion {
  int track_id = -1;
  std::string type;
  std::vector<int> frames;                  // frames where the track has an ego pose
  std::vector<Eigen::Vector3d> p_in_world;  // box centre in the ego world frame, per frame
  std::vector<double> speed_mps;            // windowed speed per frame (see ComputeTrackMotion)
  double median_speed_mps = 0;  // of speed_mps; an even count averages the two middle values
  double displacement_m = 0;    // first to last world position
};

// World motion of every track, using ego poses world_from_cam0 indexed by frame (frame_index
// of each pose, or its position when frame_index < 0) with t_ns stamps (0.1 s per frame is
// assumed when all stamps are 0). The speed at a frame is the distance between the positions
// about window_s/2 before and after it (clamped at the track ends) over the time between them;
// tracks observed for less than window_s/2 get the end-to-end speed.
std::map<int, TrackMotion> ComputeTrackMotion(const TrackingLabels& labels,
                                              const Trajectory& world_from_cam0,
                                              double window_s = 1.0);

// A track moves when its median windowed speed exceeds threshold_mps.
bool IsMoving(const TrackMotion& motion, double threshold_mps);
// The object of track_id is moving at `frame` (windowed speed above threshold_mps); false when
// the track is not observed at that frame.
bool IsMovingAt(const TrackMotion& motion, int frame, double threshold_mps);

}  // namespace pcr
