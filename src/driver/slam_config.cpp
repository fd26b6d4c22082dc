#include "driver/slam_config.h"

#include "slam/common/error.h"
#include "slam/dynamic/yolo_segmenter.h"

namespace pcr::driver {

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
  s.Add("stereo", "outlier_sad_factor", &st.outlier_sad_factor,
        "a match whose SAD exceeds the median's times this is dropped (default 1.5 x 1.4, "
        "ORB-SLAM's: the product as a double is 2.0999999999999996)");
  s.Add("stereo", "subpixel_fit", &c.subpixel_fit, "parabola or equiangular");
  s.Add("stereo", "slant_refinement", &st.slant_refinement,
        "Gauss-Newton refinement with a disparity gradient down the window");
  s.Add("orb", "quadtree_oversplit", &orb.quadtree_oversplit,
        "1: one corner per quadtree node (ORB-SLAM); 2: strongest of twice as many nodes");

  TrackerOptions& t = c.slam.tracker;
  s.Add("tracking", "close_depth_baselines", &t.close_depth_baselines,
        "close stereo points: depth < this * baseline");
  s.Add("tracking", "min_init_stereo_points", &t.min_init_stereo_points);
  s.Add("tracking", "motion_search_radius_px", &t.motion_search_radius_px);
  s.Add("tracking", "min_motion_matches", &t.min_motion_matches);
  s.Add("tracking", "min_pose_inliers", &t.min_pose_inliers);
  s.Add("tracking", "min_motion_inlier_ratio", &t.min_motion_inlier_ratio,
        "motion-model pose: share of its matches that must be inliers, else reference tracking");
  s.Add("tracking", "min_motion_inliers_of_last", &t.min_motion_inliers_of_last,
        "motion-model pose: inliers against the last frame's tracked points, else the same");
  s.Add("tracking", "min_local_map_inliers", &t.min_local_map_inliers);
  s.Add("tracking", "max_local_keyframes", &t.max_local_keyframes);
  s.Add("tracking", "relocalisation_keyframes", &t.relocalisation_keyframes);
  s.Add("tracking", "localisation_relocalise_below", &t.localisation_relocalise_below,
        "--localize-only: a frame with fewer map-point inliers also tries relocalisation");
  s.Add("tracking", "localisation_recheck_frames", &t.localisation_recheck_frames,
        "--localize-only: and every this many frames");
  s.Add("tracking", "reinitialise_after_lost_frames", &t.reinitialise_after_lost_frames,
        "stereo: this many lost frames with depth in a row start a new part of the map (0: never)");
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
  s.Add("keyframe", "max_rotation_since_keyframe_deg", &k.max_rotation_since_keyframe_deg);
  s.Add("keyframe", "filtered_ratio_gain", &k.filtered_ratio_gain);
  s.Add("keyframe", "max_filtered_fraction", &k.max_filtered_fraction);

  LocalMapperOptions& m = c.slam.mapping;
  s.Add("mapping", "close_depth_baselines", &m.close_depth_baselines);
  s.Add("mapping", "min_stereo_points", &m.min_stereo_points);
  s.Add("mapping", "triangulation_neighbours", &m.triangulation_neighbours);
  s.Add("mapping", "min_found_ratio", &m.min_found_ratio);
  s.Add("mapping", "fuse_neighbours", &m.fuse_neighbours);
  s.Add("mapping", "local_bundle_adjustment", &m.local_bundle_adjustment);
  s.Add("mapping", "ba_local_keyframes", &m.ba_local_keyframes,
        "0: every covisible keyframe; else the local BA optimises the best this many");
  s.Add("mapping", "ba_max_iterations", &m.bundle_adjustment.max_iterations);
  s.Add("mapping", "ba_optimise_twice", &m.bundle_adjustment.optimise_twice);
  s.Add("mapping", "cull_keyframes", &m.cull_keyframes);
  s.Add("mapping", "redundant_fraction", &m.redundant_fraction);
  s.Add("mapping", "max_keyframes", &m.max_keyframes,
        "0: unbounded; else the oldest keyframes beyond it are forgotten (bounded memory)");

  LoopClosingOptions& l = c.slam.loop;
  s.Add("loop", "enabled", &l.enabled, "loop closing and place recognition (needs a vocabulary)");
  s.Add("loop", "min_keyframes", &l.min_keyframes);
  s.Add("loop", "exclude_recent_keyframes", &l.exclude_recent_keyframes,
        "keyframes this close (insertion order) to the query are never loop candidates");
  s.Add("loop", "consistency", &l.consistency,
        "consecutive keyframes whose candidate groups must agree");
  s.Add("loop", "min_bow_matches", &l.min_bow_matches);
  s.Add("loop", "ransac_precheck", &l.ransac_precheck);
  s.Add("loop", "min_ransac_inliers", &l.min_ransac_inliers);
  s.Add("loop", "min_sim3_inliers", &l.min_sim3_inliers);
  s.Add("loop", "min_loop_matches", &l.min_loop_matches);
  s.Add("loop", "join_evidence_factor", &l.join_evidence_factor,
        "a loop that joins two parts of the map needs this many times min_sim3_inliers and "
        "min_loop_matches");
  s.Add("loop", "covisibility_edge_weight", &l.covisibility_edge_weight);
  s.Add("loop", "pose_graph_iterations", &l.pose_graph_iterations);
  s.Add("loop", "global_bundle_adjustment", &l.global_bundle_adjustment);
  s.Add("loop", "global_ba_iterations", &l.global_ba_iterations);
  s.Add("loop", "global_ba_optimise_twice", &l.global_ba_optimise_twice,
        "second global BA solve without the first one's outlier observations");
  s.Add("loop", "final_global_ba", &l.final_global_ba,
        "stereo: after a run that closed a loop, one more global BA over the whole map when "
        "keyframes came after the last one");
  s.Add("loop", "final_global_ba_mono", &l.final_global_ba_mono,
        "loop.final_global_ba for monocular maps");
  s.Add("loop", "final_global_ba_min_keyframes", &l.final_global_ba_min_keyframes,
        "loop.final_global_ba only when at least this many keyframes came after the last global "
        "BA");
  s.Add("loop", "skip_keyframes_after_loop", &l.skip_keyframes_after_loop);
  s.Add("loop", "sequence_length", &l.sequence_length,
        "0: loop candidates by single keyframes (ORB-SLAM's); else over sequences of this many "
        "keyframes (SeqSLAM's idea on bag-of-words scores)");
  s.Add("loop", "sequence_min_length", &l.sequence_min_length,
        "fewest keyframe pairs a sequence score needs");
  s.Add("loop", "sequence_uniqueness", &l.sequence_uniqueness,
        "a sequence answer must score this many times the best keyframe elsewhere (>= 1)");
  s.Add("loop", "sequence_window", &l.sequence_window,
        "keyframes this close to the sequence answer are not 'elsewhere'");
  s.Add("loop", "sequence_neighbours", &l.sequence_neighbours,
        "keyframes either side of the sequence answer verified with it (the most loop matches "
        "wins)");
  s.Add("loop", "sequence_consistency", &l.sequence_consistency,
        "over sequences: consecutive keyframes whose candidate groups must agree");
  s.Add("loop", "incremental_snapshots", &l.incremental_snapshots,
        "loop jobs carry the map edits since the previous job, not a copy of the map");
  s.Add("loop", "max_snapshot_edits", &l.max_snapshot_edits,
        "more map edits between two jobs: the next job carries a copy (0: no limit)");

  s.Add("segmenter", "crop_top_to_fill_width", &c.dynamic.crop_top_to_fill_width,
        "a YOLO input wider than the frame takes it at full width, its top rows cut");
  s.Add("segmenter", "conf_threshold", &c.dynamic.conf_threshold,
        "YOLO: an instance's best class score must exceed this (0..1)");
  s.Add("segmenter", "mask_threshold", &c.dynamic.mask_threshold,
        "YOLO: a pixel is in an instance's mask where sigmoid(coefficients . prototypes) exceeds "
        "this (0..1)");
  s.Add("segmenter", "light_mask_threshold", &c.dynamic.light_mask_threshold,
        "the same for the adaptive light network (--model-low; < 0: mask_threshold)");

  DynamicFilterOptions& f = c.dynamic.options;
  s.Add("filter", "exclude_below", &f.scoring.exclude_below, "Eq. 2 scores below this: excluded");
  s.Add("filter", "weight_mask", &f.scoring.weights.mask, "Eq. 2 weights (sum 1)");
  s.Add("filter", "weight_motion", &f.scoring.weights.motion);
  s.Add("filter", "weight_ground", &f.scoring.weights.ground);
  s.Add("filter", "weight_edge", &f.scoring.weights.edge);
  s.Add("filter", "weight_relative_to_uninformed", &f.scoring.weight_relative_to_uninformed,
        "optimiser weight = score / score of an untested point (false: the score)");
  s.Add("filter", "keep_masked_static_above", &f.scoring.keep_masked_static_above,
        "masked points with no motion seen (P(static) >= this) but blind tests: kept (> 1: off)");
  s.Add("filter", "remove_ground", &f.ground.remove_ground, "false: down-weight ground points");
  s.Add("filter", "ground_motion_unreliable", &f.scoring.ground_motion_unreliable,
        "motion on road outside masks (shadows): excluded as unreliable, not a moving object");
  s.Add("filter", "reference_speed_mps", &f.motion.reference_speed_mps,
        "motion the test must see before it confirms a point static");
  s.Add("filter", "lk_sigma_px", &f.lk_sigma_px);
  s.Add("filter", "lk_window_px", &f.lk.window_px, "side of the motion test's LK window (odd)");
  s.Add("filter", "lk_max_level", &f.lk.max_level, "LK pyramid levels above the base");
  s.Add("filter", "lk_max_iterations", &f.lk.max_iterations, "LK iterations per level");
  s.Add("filter", "long_baseline_frames", &f.long_baseline_frames, "0: one-frame motion test only");
  s.Add("filter", "temporal_window_frames", &f.voting.window_frames, "Eq. 4 window");
  s.Add("filter", "vote_threshold", &f.voting.dynamic_threshold, "log-odds of 'moving'");
  s.Add("filter", "instance_memory_frames", &f.instance_memory.max_age_frames);
  s.Add("filter", "instance_informative_observability", &f.instances.informative_observability,
        "instance verdicts: blind points below this do not count (0: all observed points)");
  s.Add("filter", "cross_check_depth_motion", &f.cross_check_depth_motion);
  s.Add("filter", "keep_first_frame_masks", &f.keep_first_frame_masks);
  s.Add("filter", "use_previous_disparity", &f.use_previous_disparity,
        "depth test also compares the previous frame's disparity (3 dof)");

  s.Add("camera", "fx", &c.camera.fx, "0: use the dataset's calibration");
  s.Add("camera", "fy", &c.camera.fy);
  s.Add("camera", "cx", &c.camera.cx);
  s.Add("camera", "cy", &c.camera.cy);
  s.Add("camera", "baseline_m", &c.camera.baseline_m);
}

namespace {

// The first problem of a configuration ("" when none), as "invalid configuration: ..."; sets
// the fields derived from others (stereo.subpixel_fit).
std::string Problem(RunConfig& config) {
  if (config.subpixel_fit == "parabola") {
    config.slam.stereo.subpixel_fit = SubpixelFit::kParabola;
  } else if (config.subpixel_fit == "equiangular") {
    config.slam.stereo.subpixel_fit = SubpixelFit::kEquiangular;
  } else {
    return "stereo.subpixel_fit must be parabola or equiangular, not '" + config.subpixel_fit + "'";
  }
  std::string why;
  if (!config.slam.IsValid(&why)) return "invalid configuration: " + why;
  if (!config.camera.IsValid(&why)) return "invalid configuration: " + why;
  if (!config.dynamic.options.IsValid(&why)) return "invalid configuration: filter: " + why;
  const DynamicRunOptions& d = config.dynamic;
  // The segmenter's model path is not known here, so only its thresholds are checked (the same
  // range as YoloOptions::IsValid; a negative light_mask_threshold means mask_threshold).
  if (!YoloOptions::IsThresholdInRange(d.conf_threshold) ||
      !YoloOptions::IsThresholdInRange(d.mask_threshold) ||
      !(d.light_mask_threshold < 0 || YoloOptions::IsThresholdInRange(d.light_mask_threshold))) {
    return "invalid configuration: segmenter: conf_threshold and mask_threshold must lie in (0, "
           "1), light_mask_threshold too or be negative (the same)";
  }
  return "";
}

}  // namespace

RunConfig LoadRunConfig(const std::string& path, const std::vector<std::string>& overrides,
                        std::string* effective_yaml, const OptionNames& names) {
  const std::string set = Named(names, "--set");
  RunConfig config;
  ConfigSchema schema;
  BindRunConfig(config, schema);
  if (!path.empty()) schema.LoadFile(path);
  for (const std::string& o : overrides) schema.Set(o, set);
  const std::string problem = Problem(config);
  if (!problem.empty()) {
    // Where the offending value came from: the file and the key's line, or --set and the key;
    // where no single value is to blame (a missing key), the sources that were read.
    if (const auto origin = schema.Blame([&config] { return Problem(config); })) {
      if (origin->line > 0)
        throw ConfigError(origin->source + ":" + std::to_string(origin->line) + ": " + problem);
      throw ConfigError(origin->source + " " + origin->name + ": " + problem);
    }
    std::string source = "defaults";
    if (!path.empty() && !overrides.empty()) {
      source = path + " + " + set;
    } else if (!path.empty()) {
      source = path;
    } else if (!overrides.empty()) {
      source = set;
    }
    throw ConfigError(source + ": " + problem);
  }
  if (effective_yaml) *effective_yaml = schema.Dump();
  return config;
}

}  // namespace pcr::driver
