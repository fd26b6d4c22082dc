#include "app/slam_config.h"

#include "slam/common/error.h"

namespace pcr::app {

bool CameraOverride::IsValid(std::string* why) const {
  if (!Active()) return true;
  if (fx <= 0 || fy <= 0 || cx <= 0 || cy <= 0) {
    if (why) *why = "camera: give all of fx, fy, cx, cy (missing or non-positive key)";
    return false;
  }
  if (baseline_m < 0) {
    if (why) *why = "camera.baseline_m must be >= 0";
    return false;
  }
  return true;
}

void BindRunConfig(RunConfig& c, ConfigSchema& s) {
  OrbOptions& orb = c.slam.orb;
  s.Add("orb", "num_features", &orb.num_features, "keypoints requested per image");
  s.Add("orb", "scale_factor", &orb.scale_factor, "pyramid scale between levels");
  s.Add("orb", "num_levels", &orb.num_levels);
  s.Add("orb", "fast_threshold_high", &orb.fast_threshold_high);
  s.Add("orb", "fast_threshold_low", &orb.fast_threshold_low);
  s.Add("orb", "edge_threshold_px", &orb.edge_threshold_px);

  StereoMatchOptions& st = c.slam.stereo;
  s.Add("stereo", "max_descriptor_distance", &st.max_descriptor_distance);
  s.Add("stereo", "min_depth_m", &st.min_depth_m, "0: baseline");
  s.Add("stereo", "max_depth_m", &st.max_depth_m, "0: no limit");
  s.Add("stereo", "sad_window_half_px", &st.sad_window_half_px);
  s.Add("stereo", "sad_search_half_px", &st.sad_search_half_px);
  s.Add("stereo", "outlier_sad_factor", &st.outlier_sad_factor);
  s.Add("stereo", "subpixel_fit", &c.subpixel_fit, "parabola or equiangular");
  s.Add("orb", "quadtree_oversplit", &orb.quadtree_oversplit,
        "1: one corner per quadtree node (ORB-SLAM); 2: strongest of twice as many nodes");

  TrackerOptions& t = c.slam.tracker;
  s.Add("tracking", "close_depth_baselines", &t.close_depth_baselines,
        "close stereo points: depth < this * baseline");
  s.Add("tracking", "min_init_stereo_points", &t.min_init_stereo_points);
  s.Add("tracking", "motion_search_radius_px", &t.motion_search_radius_px);
  s.Add("tracking", "min_motion_matches", &t.min_motion_matches);
  s.Add("tracking", "min_pose_inliers", &t.min_pose_inliers);
  s.Add("tracking", "min_local_map_inliers", &t.min_local_map_inliers);
  s.Add("tracking", "max_local_keyframes", &t.max_local_keyframes);
  s.Add("tracking", "relocalisation_keyframes", &t.relocalisation_keyframes);
  s.Add("tracking", "pose_rounds", &t.pose.rounds, "outlier rounds of the pose optimisation");
  s.Add("tracking", "pose_iterations_per_round", &t.pose.iterations_per_round);
  s.Add("tracking", "chi2_mono", &t.pose.chi2_mono);
  s.Add("tracking", "chi2_stereo", &t.pose.chi2_stereo);

  KeyframeDecisionOptions& k = c.slam.keyframe;
  s.Add("keyframe", "reference_ratio", &k.reference_ratio);
  s.Add("keyframe", "min_tracked_close", &k.min_tracked_close);
  s.Add("keyframe", "min_new_close", &k.min_new_close);
  s.Add("keyframe", "max_interval_s", &k.max_interval_s);
  s.Add("keyframe", "min_interval_s", &k.min_interval_s);
  s.Add("keyframe", "filtered_ratio_gain", &k.filtered_ratio_gain);
  s.Add("keyframe", "max_filtered_fraction", &k.max_filtered_fraction);

  LocalMapperOptions& m = c.slam.mapping;
  s.Add("mapping", "close_depth_baselines", &m.close_depth_baselines);
  s.Add("mapping", "min_stereo_points", &m.min_stereo_points);
  s.Add("mapping", "triangulation_neighbours", &m.triangulation_neighbours);
  s.Add("mapping", "min_found_ratio", &m.min_found_ratio);
  s.Add("mapping", "fuse_neighbours", &m.fuse_neighbours);
  s.Add("mapping", "local_bundle_adjustment", &m.local_bundle_adjustment);
  s.Add("mapping", "ba_max_iterations", &m.bundle_adjustment.max_iterations);
  s.Add("mapping", "ba_optimise_twice", &m.bundle_adjustment.optimise_twice);
  s.Add("mapping", "cull_keyframes", &m.cull_keyframes);
  s.Add("mapping", "redundant_fraction", &m.redundant_fraction);

  s.Add("camera", "fx", &c.camera.fx, "0: use the dataset's calibration");
  s.Add("camera", "fy", &c.camera.fy);
  s.Add("camera", "cx", &c.camera.cx);
  s.Add("camera", "cy", &c.camera.cy);
  s.Add("camera", "baseline_m", &c.camera.baseline_m);
}

RunConfig LoadRunConfig(const std::string& path, const std::vector<std::string>& overrides,
                        std::string* effective_yaml) {
  RunConfig config;
  ConfigSchema schema;
  BindRunConfig(config, schema);
  if (!path.empty()) schema.LoadFile(path);
  for (const std::string& o : overrides) schema.Set(o, "--set");
  if (config.subpixel_fit == "parabola") {
    config.slam.stereo.subpixel_fit = SubpixelFit::kParabola;
  } else if (config.subpixel_fit == "equiangular") {
    config.slam.stereo.subpixel_fit = SubpixelFit::kEquiangular;
  } else {
    throw ConfigError((path.empty() ? std::string("--set") : path) +
                      ": stereo.subpixel_fit must be parabola or equiangular, not '" +
                      config.subpixel_fit + "'");
  }
  std::string why;
  const std::string source = path.empty() ? std::string("defaults") : path;
  if (!config.slam.IsValid(&why)) throw ConfigError(source + ": invalid configuration: " + why);
  if (!config.camera.IsValid(&why)) throw ConfigError(source + ": invalid configuration: " + why);
  if (effective_yaml) *effective_yaml = schema.Dump();
  return config;
}

}  // namespace pcr::app
