#pragma once
// A saved map: everything a SlamSystem needs to continue from a map it made (its keyframes with
// their keypoints, descriptors and poses, the map points, covisibility and spanning tree, the
// map's bookkeeping, and the place-recognition database when there was a vocabulary), and the
// byte format that keeps it (pure: no files; the driver reads and writes them,
// driver/map_file.h).
//
// Format version 1, integers little-endian, floats and doubles as their IEEE-754 bits:
//   "PCRMAP" (6 bytes), u16 format version, u8 mode (0 stereo, 1 monocular)
//   camera: f64 fx, fy, cx, cy, i32 width, height, f64 baseline
//   scale pyramid: u64 levels, then f64 scale factors, sigma^2, 1/sigma^2 per level
//   bookkeeping: i64 next point id, next keyframe index, first keyframe, last keyframe;
//     u64 count + (i64 merged point, i64 into) ...; u64 count + (i64 erased keyframe,
//     i64 parent, 12 f64 cam_from_parent (3x4, row-major)) ...
//   keyframes: u64 count, then per keyframe: i64 id, i64 index, 12 f64 cam_from_world, i64 t_ns,
//     u64 keypoints, per keypoint f32 x, y, size, angle, response, i32 octave, class id; the
//     descriptors (32 bytes each); per keypoint f32 right x, f32 depth, f32 weight, u8 excluded,
//     u8 grey, i64 map point (-1: none); u64 count + (i64 keyframe, i32 weight) connections;
//     the same for the covisible list; i64 parent; u64 count + i64 children
//   map points: u64 count, then per point: i64 id, 3 f64 position, 32 bytes descriptor,
//     3 f64 normal, f64 min and max distance, u64 count + (i64 keyframe, i32 keypoint)
//     observations, i64 reference keyframe, i64 first keyframe index, i32 visible, i32 found
//   place recognition: u8 present; when 1: u64 vocabulary fingerprint, i32 direct-index level,
//     u64 count + (i64 keyframe, u64 count + (u32 word, f64 weight)) bags of words,
//     u64 count + (i64 keyframe, u64 count + (u32 node, u64 count + i32 rows)) direct indices,
//     u64 count + (i64, i64) loop edges
//   u64 FNV-1a 64 of every byte before it
// Deterministic: ordered containers throughout, so the same map gives the same bytes (a map
// loaded and saved again is byte-identical).
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "slam/common/camera.h"
#include "slam/loop/loop_closer.h"
#include "slam/map/map.h"
#include "slam/map/scale_pyramid.h"
#include "slam/system/slam_system.h"

namespace pcr {

inline constexpr uint16_t kMapFormatVersion = 1;
// The first bytes of every file of this format.
inline constexpr std::string_view kMapArchiveMagic = "PCRMAP";

struct MapArchive {
  SlamMode mode = SlamMode::kStereo;
  StereoRig rig;       // the camera the keyframes were made with (baseline 0: monocular)
  ScalePyramid scale;  // their ORB pyramid
  Map map;
  // Absent when the map was made without a vocabulary (and loaded from a map without one).
  std::optional<PlaceArchive> place;
};

std::vector<uint8_t> SerializeMapArchive(const MapArchive& archive);

// Reads the format back. Throws pcr::InputError(name, 0, reason) on a foreign, truncated,
// corrupted (checksum) or inconsistent buffer (Map::Restore's and Frame::Restore's checks).
// verify_checksum = false skips the checksum only (the fuzz target, to reach the body's checks).
MapArchive DeserializeMapArchive(const uint8_t* data, size_t size, const std::string& name,
                                 bool verify_checksum = true);

}  // namespace pcr
