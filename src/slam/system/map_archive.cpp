#include "slam/system/map_archive.h"

#include <cstring>
#include <map>
#include <set>
#include <stdexcept>
#include <utility>

#include "slam/common/byte_codec.h"
#include "slam/common/error.h"

namespace pcr {
namespace {

constexpr std::string_view kMagic = kMapArchiveMagic;
constexpr size_t kChecksumBytes = 8;
constexpr size_t kPoseBytes = 12 * 8;
// Smallest encodings, for the reader's count checks.
constexpr size_t kKeypointBytes = 7 * 4 + 32 + 3 * 4 + 2 + 8;
constexpr size_t kKeyframeMinBytes = 8 + 8 + kPoseBytes + 8 + 8 + 8 + 8 + 8 + 8;
constexpr size_t kPointMinBytes = 8 + 24 + 32 + 24 + 16 + 8 + 8 + 8 + 4 + 4;

// The keys of the format's ordered containers are stored increasing: a key out of order or
// stored twice would be re-sorted or dropped, and the map would not save back to the bytes it
// was read from. last: the key read before (null for the first).
template <typename Id>
void CheckAfter(const Id* last, Id id, const std::string& what, ByteReader* r) {
  if (last && !(*last < id))
    r->Fail(what + " " + std::to_string(id.value) + " out of order or stored twice");
}

template <typename K, typename V>
const K* LastKey(const std::map<K, V>& m) {
  return m.empty() ? nullptr : &m.rbegin()->first;
}

template <typename K>
const K* LastKey(const std::set<K>& s) {
  return s.empty() ? nullptr : &*s.rbegin();
}

void PutPose(const SE3& pose, ByteWriter* w) {
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) w->F64(pose.matrix()(r, c));
}

SE3 GetPose(ByteReader* r) {
  SE3 pose = SE3::Identity();
  for (int i = 0; i < 3; ++i)
    for (int c = 0; c < 4; ++c) pose.matrix()(i, c) = r->F64();
  return pose;
}

void PutVector3(const Eigen::Vector3d& v, ByteWriter* w) {
  for (int i = 0; i < 3; ++i) w->F64(v[i]);
}

Eigen::Vector3d GetVector3(ByteReader* r) {
  Eigen::Vector3d v;
  for (int i = 0; i < 3; ++i) v[i] = r->F64();
  return v;
}

void PutDescriptor(const cv::Mat& row, ByteWriter* w) {
  uint8_t bytes[32] = {};
  if (row.rows == 1 && row.cols == 32 && row.type() == CV_8U) std::memcpy(bytes, row.ptr(0), 32);
  w->Raw(bytes, 32);
}

cv::Mat GetDescriptor(ByteReader* r) {
  cv::Mat row(1, 32, CV_8U);
  r->Raw(row.ptr(0), 32);
  return row;
}

void PutDoubles(const std::vector<double>& v, ByteWriter* w) {
  for (double d : v) w->F64(d);
}

std::vector<double> GetDoubles(size_t n, ByteReader* r) {
  std::vector<double> v(n);
  for (double& d : v) d = r->F64();
  return v;
}

void PutKeyframe(const Keyframe& kf, ByteWriter* w) {
  const Frame& f = *kf.frame;
  w->I64(kf.id.value);
  w->I64(kf.index);
  PutPose(kf.cam_from_world, w);
  w->I64(f.t_ns());
  w->U64(static_cast<uint64_t>(f.size()));
  for (const cv::KeyPoint& kp : f.keypoints()) {
    w->F32(kp.pt.x);
    w->F32(kp.pt.y);
    w->F32(kp.size);
    w->F32(kp.angle);
    w->F32(kp.response);
    w->I32(kp.octave);
    w->I32(kp.class_id);
  }
  for (int i = 0; i < f.size(); ++i) PutDescriptor(f.descriptors().row(i), w);
  for (int i = 0; i < f.size(); ++i) {
    w->F32(f.u_right_px(i));
    w->F32(f.depth_m(i));
    w->F32(f.weight(i));
    w->U8(f.excluded(i) ? 1 : 0);
    w->U8(f.grey(i));
    w->I64(kf.points[static_cast<size_t>(i)].value);
  }
  w->U64(kf.connections.size());
  for (const auto& [other, weight] : kf.connections) {
    w->I64(other.value);
    w->I32(weight);
  }
  w->U64(kf.covisible.size());
  for (const auto& [other, weight] : kf.covisible) {
    w->I64(other.value);
    w->I32(weight);
  }
  w->I64(kf.parent.value);
  w->U64(kf.children.size());
  for (KeyframeId c : kf.children) w->I64(c.value);
}

Keyframe GetKeyframe(const StereoRig& rig, const ScalePyramid& scale, ByteReader* r) {
  Keyframe kf;
  kf.id = KeyframeId(r->I64());
  kf.index = r->I64();
  kf.cam_from_world = GetPose(r);
  const int64_t t_ns = r->I64();
  const size_t n = r->Count(kKeypointBytes, "keypoint");
  std::vector<cv::KeyPoint> keypoints(n);
  for (cv::KeyPoint& kp : keypoints) {
    kp.pt.x = r->F32();
    kp.pt.y = r->F32();
    kp.size = r->F32();
    kp.angle = r->F32();
    kp.response = r->F32();
    kp.octave = r->I32();
    kp.class_id = r->I32();
  }
  cv::Mat descriptors(static_cast<int>(n), 32, CV_8U);
  if (n > 0) r->Raw(descriptors.ptr(0), n * 32);
  StereoMatches stereo;
  KeypointFilter filter;
  std::vector<uint8_t> grey(n);
  stereo.u_right_px.resize(n);
  stereo.depth_m.resize(n);
  filter.weight.resize(n);
  filter.excluded.resize(n);
  kf.points.resize(n);
  for (size_t i = 0; i < n; ++i) {
    stereo.u_right_px[i] = r->F32();
    stereo.depth_m[i] = r->F32();
    filter.weight[i] = r->F32();
    filter.excluded[i] = r->U8();
    if (filter.excluded[i] > 1)
      r->Fail("keyframe " + std::to_string(kf.id.value) + ": excluded flag of keypoint " +
              std::to_string(i) + " is not 0 or 1");
    grey[i] = r->U8();
    kf.points[i] = MapPointId(r->I64());
  }
  try {
    kf.frame =
        Frame::Restore(kf.id.value, t_ns, rig, scale, keypoints, descriptors, stereo, filter, grey);
  } catch (const std::invalid_argument& e) {
    r->Fail("keyframe " + std::to_string(kf.id.value) + ": " + e.what());
  }
  const size_t num_connections = r->Count(12, "connection");
  for (size_t i = 0; i < num_connections; ++i) {
    const KeyframeId other(r->I64());
    CheckAfter(LastKey(kf.connections), other,
               "keyframe " + std::to_string(kf.id.value) + ": connection to keyframe", r);
    kf.connections[other] = r->I32();
  }
  const size_t num_covisible = r->Count(12, "covisible keyframe");
  for (size_t i = 0; i < num_covisible; ++i) {
    const KeyframeId other(r->I64());
    kf.covisible.emplace_back(other, r->I32());
  }
  kf.parent = KeyframeId(r->I64());
  const size_t num_children = r->Count(8, "child");
  for (size_t i = 0; i < num_children; ++i) {
    const KeyframeId child(r->I64());
    CheckAfter(LastKey(kf.children), child,
               "keyframe " + std::to_string(kf.id.value) + ": child keyframe", r);
    kf.children.insert(child);
  }
  return kf;
}

void PutPoint(const MapPoint& mp, ByteWriter* w) {
  w->I64(mp.id.value);
  PutVector3(mp.p_in_world, w);
  PutDescriptor(mp.descriptor, w);
  PutVector3(mp.normal, w);
  w->F64(mp.min_distance_m);
  w->F64(mp.max_distance_m);
  w->U64(mp.observations.size());
  for (const auto& [kf, kp] : mp.observations) {
    w->I64(kf.value);
    w->I32(kp);
  }
  w->I64(mp.reference_keyframe.value);
  w->I64(mp.first_keyframe_index);
  w->I32(mp.visible_count);
  w->I32(mp.found_count);
}

MapPoint GetPoint(ByteReader* r) {
  MapPoint mp;
  mp.id = MapPointId(r->I64());
  mp.p_in_world = GetVector3(r);
  mp.descriptor = GetDescriptor(r);
  mp.normal = GetVector3(r);
  mp.min_distance_m = r->F64();
  mp.max_distance_m = r->F64();
  const size_t n = r->Count(12, "observation");
  for (size_t i = 0; i < n; ++i) {
    const KeyframeId kf(r->I64());
    CheckAfter(LastKey(mp.observations), kf,
               "map point " + std::to_string(mp.id.value) + ": observation in keyframe", r);
    mp.observations[kf] = r->I32();
  }
  mp.reference_keyframe = KeyframeId(r->I64());
  mp.first_keyframe_index = r->I64();
  mp.visible_count = r->I32();
  mp.found_count = r->I32();
  return mp;
}

void PutPlace(const PlaceArchive& place, ByteWriter* w) {
  w->U64(place.vocabulary_fingerprint);
  w->I32(place.direct_index_levels_up);
  w->U64(place.bows.size());
  for (const auto& [id, bow] : place.bows) {
    w->I64(id.value);
    w->U64(bow.words.size());
    for (const auto& [word, weight] : bow.words) {
      w->U32(word);
      w->F64(weight);
    }
  }
  w->U64(place.features.size());
  for (const auto& [id, features] : place.features) {
    w->I64(id.value);
    w->U64(features.nodes.size());
    for (const auto& [node, rows] : features.nodes) {
      w->U32(node);
      w->U64(rows.size());
      for (int row : rows) w->I32(row);
    }
  }
  w->U64(place.loop_edges.size());
  for (const auto& [a, b] : place.loop_edges) {
    w->I64(a.value);
    w->I64(b.value);
  }
}

PlaceArchive GetPlace(ByteReader* r) {
  PlaceArchive place;
  place.vocabulary_fingerprint = r->U64();
  place.direct_index_levels_up = r->I32();
  const size_t num_bows = r->Count(16, "bag of words");
  for (size_t i = 0; i < num_bows; ++i) {
    const KeyframeId id(r->I64());
    CheckAfter(LastKey(place.bows), id, "bag of words of keyframe", r);
    BowVector& bow = place.bows[id];
    bow.words.resize(r->Count(12, "word"));
    for (auto& [word, weight] : bow.words) {
      word = r->U32();
      weight = r->F64();
    }
  }
  const size_t num_features = r->Count(16, "direct index");
  for (size_t i = 0; i < num_features; ++i) {
    const KeyframeId id(r->I64());
    CheckAfter(LastKey(place.features), id, "direct index of keyframe", r);
    FeatureVector& features = place.features[id];
    features.nodes.resize(r->Count(12, "direct-index node"));
    for (auto& [node, rows] : features.nodes) {
      node = r->U32();
      rows.resize(r->Count(4, "direct-index row"));
      for (int& row : rows) row = r->I32();
    }
  }
  const size_t num_edges = r->Count(16, "loop edge");
  for (size_t i = 0; i < num_edges; ++i) {
    const KeyframeId a(r->I64());
    place.loop_edges.emplace_back(a, KeyframeId(r->I64()));
  }
  return place;
}

}  // namespace

std::vector<uint8_t> SerializeMapArchive(const MapArchive& archive) {
  ByteWriter w;
  w.Raw(kMagic.data(), kMagic.size());
  w.U16(kMapFormatVersion);
  w.U8(archive.mode == SlamMode::kMonocular ? 1 : 0);
  const PinholeCamera& c = archive.rig.left;
  w.F64(c.fx);
  w.F64(c.fy);
  w.F64(c.cx);
  w.F64(c.cy);
  w.I32(c.width_px);
  w.I32(c.height_px);
  w.F64(archive.rig.baseline_m);
  const ScalePyramid& s = archive.scale;
  w.U64(s.scale_factors.size());
  PutDoubles(s.scale_factors, &w);
  PutDoubles(s.level_sigma2, &w);
  PutDoubles(s.inv_level_sigma2, &w);

  const Map& map = archive.map;
  const Map::Bookkeeping b = map.bookkeeping();
  w.I64(b.next_point_id);
  w.I64(b.next_keyframe_index);
  w.I64(b.first_keyframe.value);
  w.I64(b.last_keyframe.value);
  w.U64(b.replaced_by.size());
  for (const auto& [from, into] : b.replaced_by) {
    w.I64(from.value);
    w.I64(into.value);
  }
  w.U64(b.erased_keyframes.size());
  for (const auto& [id, erased] : b.erased_keyframes) {
    w.I64(id.value);
    w.I64(erased.parent.value);
    PutPose(erased.cam_from_parent, &w);
  }
  w.U64(map.keyframes().size());
  for (const auto& [id, kf] : map.keyframes()) PutKeyframe(kf, &w);
  w.U64(map.points().size());
  for (const auto& [id, mp] : map.points()) PutPoint(mp, &w);
  w.U8(archive.place ? 1 : 0);
  if (archive.place) PutPlace(*archive.place, &w);
  w.Checksum();
  return std::move(w.bytes());
}

MapArchive DeserializeMapArchive(const uint8_t* data, size_t size, const std::string& name,
                                 bool verify_checksum) {
  auto fail = [&name](const std::string& reason) { throw InputError(name, 0, reason); };
  if (size < kMagic.size() || std::memcmp(data, kMagic.data(), kMagic.size()) != 0)
    fail("not a PCR-ORB map (no PCRMAP magic)");
  if (size < kMagic.size() + 3 + kChecksumBytes)
    fail("truncated map: " + std::to_string(size) + " bytes");
  const uint64_t version = GetLittleEndian(data + kMagic.size(), 2);
  if (version != kMapFormatVersion) {
    fail("unsupported map format version " + std::to_string(version) + " (this build reads " +
         std::to_string(kMapFormatVersion) + ")");
  }
  const size_t body = size - kChecksumBytes;
  if (verify_checksum && GetLittleEndian(data + body, 8) != Fnv1a64(data, body))
    fail("checksum mismatch: the map file is truncated or corrupted");

  ByteReader r(data, body, name);
  uint8_t skip[kMagic.size() + 2];
  r.Raw(skip, sizeof skip);
  MapArchive archive;
  const uint8_t mode = r.U8();
  if (mode > 1) r.Fail("unknown SLAM mode " + std::to_string(mode));
  archive.mode = mode == 1 ? SlamMode::kMonocular : SlamMode::kStereo;
  PinholeCamera& c = archive.rig.left;
  c.fx = r.F64();
  c.fy = r.F64();
  c.cx = r.F64();
  c.cy = r.F64();
  c.width_px = r.I32();
  c.height_px = r.I32();
  archive.rig.baseline_m = r.F64();
  std::string why;
  if (!archive.rig.IsValid(&why) || c.width_px <= 0 || c.height_px <= 0)
    r.Fail("invalid camera: " + (why.empty() ? std::string("no image size") : why));
  const size_t levels = r.Count(24, "pyramid level");
  ScalePyramid& s = archive.scale;
  s.scale_factors = GetDoubles(levels, &r);
  s.level_sigma2 = GetDoubles(levels, &r);
  s.inv_level_sigma2 = GetDoubles(levels, &r);
  if (!s.IsValid(&why)) r.Fail("invalid scale pyramid: " + why);

  Map::Bookkeeping b;
  b.next_point_id = r.I64();
  b.next_keyframe_index = r.I64();
  b.first_keyframe = KeyframeId(r.I64());
  b.last_keyframe = KeyframeId(r.I64());
  const size_t num_replaced = r.Count(16, "merged point");
  for (size_t i = 0; i < num_replaced; ++i) {
    const MapPointId from(r.I64());
    CheckAfter(b.replaced_by.empty() ? nullptr : &b.replaced_by.back().first, from, "merged point",
               &r);
    b.replaced_by.emplace_back(from, MapPointId(r.I64()));
  }
  const size_t num_erased = r.Count(16 + kPoseBytes, "erased keyframe");
  for (size_t i = 0; i < num_erased; ++i) {
    const KeyframeId id(r.I64());
    CheckAfter(LastKey(b.erased_keyframes), id, "erased keyframe", &r);
    Map::ErasedKeyframe erased;
    erased.parent = KeyframeId(r.I64());
    erased.cam_from_parent = GetPose(&r);
    b.erased_keyframes[id] = erased;
  }
  std::map<KeyframeId, Keyframe> keyframes;
  const size_t num_keyframes = r.Count(kKeyframeMinBytes, "keyframe");
  for (size_t i = 0; i < num_keyframes; ++i) {
    Keyframe kf = GetKeyframe(archive.rig, archive.scale, &r);
    const KeyframeId id = kf.id;
    CheckAfter(LastKey(keyframes), id, "keyframe", &r);
    keyframes.emplace(id, std::move(kf));
  }
  std::map<MapPointId, MapPoint> points;
  const size_t num_points = r.Count(kPointMinBytes, "map point");
  for (size_t i = 0; i < num_points; ++i) {
    MapPoint mp = GetPoint(&r);
    const MapPointId id = mp.id;
    CheckAfter(LastKey(points), id, "map point", &r);
    points.emplace(id, std::move(mp));
  }
  const uint8_t has_place = r.U8();
  if (has_place > 1) r.Fail("corrupted place-recognition flag");
  if (has_place) archive.place = GetPlace(&r);
  if (r.remaining() != 0)
    r.Fail(std::to_string(r.remaining()) + " bytes after the map's last section");
  try {
    archive.map = Map::Restore(std::move(keyframes), std::move(points), std::move(b));
  } catch (const std::invalid_argument& e) {
    fail(e.what());
  }
  return archive;
}

}  // namespace pcr
