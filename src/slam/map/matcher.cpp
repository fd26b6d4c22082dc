#include "slam/map/matcher.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/features2d.hpp>

#include "slam/common/lie.h"

namespace pcr {
namespace {

constexpr double kChi2Mono = 5.991;
constexpr double kChi2Stereo = 7.8;

void DropRejected(const RotationConsistency& rotation, std::vector<int>* current_to_candidate,
                  int* count) {
  for (int i : rotation.Rejected()) {
    if ((*current_to_candidate)[i] >= 0) {
      (*current_to_candidate)[i] = -1;
      --*count;
    }
  }
}

}  // namespace

void RotationConsistency::Add(float angle_from_deg, float angle_to_deg, int match) {
  if (angle_from_deg < 0 || angle_to_deg < 0) return;  // no orientation: always kept
  double rot = angle_from_deg - angle_to_deg;
  while (rot < 0) rot += 360.0;
  while (rot >= 360.0) rot -= 360.0;
  const int bin = std::min(kBins - 1, static_cast<int>(rot * kBins / 360.0));
  bins_[bin].push_back(match);
}

std::vector<int> RotationConsistency::Rejected() const {
  int max1 = 0, max2 = 0, max3 = 0;
  int i1 = -1, i2 = -1, i3 = -1;
  for (int b = 0; b < kBins; ++b) {
    const int s = static_cast<int>(bins_[b].size());
    if (s > max1) {
      max3 = max2, i3 = i2;
      max2 = max1, i2 = i1;
      max1 = s, i1 = b;
    } else if (s > max2) {
      max3 = max2, i3 = i2;
      max2 = s, i2 = b;
    } else if (s > max3) {
      max3 = s, i3 = b;
    }
  }
  if (max2 < 0.1 * max1) i2 = -1;
  if (max3 < 0.1 * max1) i3 = -1;
  std::vector<int> rejected;
  for (int b = 0; b < kBins; ++b) {
    if (b == i1 || b == i2 || b == i3) continue;
    rejected.insert(rejected.end(), bins_[b].begin(), bins_[b].end());
  }
  return rejected;
}

int SearchByProjection(const Frame& current, const SE3& current_cam_from_world,
                       const SE3& last_cam_from_world,
                       const std::vector<FramePointCandidate>& candidates, double radius_px,
                       bool check_orientation, std::vector<int>* current_to_candidate) {
  std::vector<int>& assigned = *current_to_candidate;
  assigned.resize(current.size(), -1);
  const StereoRig& rig = current.rig();
  const ScalePyramid& scale = current.scale();
  // Motion along the optical axis of the last camera, in the last camera frame.
  const Eigen::Vector3d t_last_current =
      (last_cam_from_world * current_cam_from_world.inverse()).translation();
  const bool forward = rig.IsStereo() && t_last_current.z() > rig.baseline_m;
  const bool backward = rig.IsStereo() && -t_last_current.z() > rig.baseline_m;
  std::vector<int> best_dist_of_kp(current.size(), std::numeric_limits<int>::max());
  RotationConsistency rotation;
  int count = 0;
  for (size_t c = 0; c < candidates.size(); ++c) {
    const FramePointCandidate& cand = candidates[c];
    const Eigen::Vector3d p_in_cam = current_cam_from_world * cand.p_in_world;
    if (p_in_cam.z() <= 0) continue;
    const Eigen::Vector2d uv = rig.left.Project(p_in_cam);
    if (!rig.left.InImage(uv)) continue;
    const double radius = radius_px * scale.scale_factors[cand.octave];
    std::vector<int> indices;
    if (forward)
      indices = current.FeaturesInArea(uv.x(), uv.y(), radius, cand.octave, -1);
    else if (backward)
      indices = current.FeaturesInArea(uv.x(), uv.y(), radius, 0, cand.octave);
    else
      indices = current.FeaturesInArea(uv.x(), uv.y(), radius, std::max(0, cand.octave - 1),
                                       cand.octave + 1);
    if (indices.empty()) continue;
    const double u_right = rig.IsStereo() ? rig.ProjectRightX(p_in_cam) : -1;
    int best_dist = std::numeric_limits<int>::max(), best_idx = -1;
    for (int i : indices) {
      if (assigned[i] != -1) continue;
      if (rig.IsStereo() && current.u_right_px(i) > 0 &&
          std::abs(u_right - current.u_right_px(i)) > radius)
        continue;
      const int d = DescriptorDistance(cand.descriptor, current.descriptor(i));
      if (d < best_dist) {
        best_dist = d;
        best_idx = i;
      }
    }
    if (best_idx < 0 || best_dist > kDescriptorDistanceHigh) continue;
    assigned[best_idx] = static_cast<int>(c);
    ++count;
    if (check_orientation) rotation.Add(cand.angle_deg, current.keypoint(best_idx).angle, best_idx);
  }
  if (check_orientation) DropRejected(rotation, current_to_candidate, &count);
  return count;
}

int SearchLocalPoints(const Frame& current, const std::vector<ProjectedPoint>& candidates,
                      double radius_factor, std::vector<int>* current_to_candidate,
                      int levels_below, int levels_above) {
  std::vector<int>& assigned = *current_to_candidate;
  assigned.resize(current.size(), -1);
  const ScalePyramid& scale = current.scale();
  int count = 0;
  for (size_t c = 0; c < candidates.size(); ++c) {
    const ProjectedPoint& cand = candidates[c];
    const double r = (cand.view_cos > 0.998 ? 2.5 : 4.0) * radius_factor *
                     scale.scale_factors[cand.predicted_level];
    const std::vector<int> indices = current.FeaturesInArea(
        cand.uv_px.x(), cand.uv_px.y(), r, std::max(0, cand.predicted_level - levels_below),
        cand.predicted_level + levels_above);
    NearestTwo near;
    int best_level = -1, second_level = -1;
    for (int i : indices) {
      if (assigned[i] != -1) continue;
      if (cand.u_right_px >= 0 && current.u_right_px(i) > 0 &&
          std::abs(cand.u_right_px - current.u_right_px(i)) > r)
        continue;
      switch (near.Add(DescriptorDistance(cand.descriptor, current.descriptor(i)), i)) {
        case NearestTwo::Rank::kNearest:
          second_level = best_level;
          best_level = current.octave(i);
          break;
        case NearestTwo::Rank::kSecond:
          second_level = current.octave(i);
          break;
        case NearestTwo::Rank::kNone:
          break;
      }
    }
    const int best = near.nearest, best_idx = near.nearest_index;
    if (best_idx < 0 || best > kDescriptorDistanceHigh) continue;
    if (best_level == second_level && best > 0.8 * near.second) continue;
    assigned[best_idx] = static_cast<int>(c);
    ++count;
  }
  return count;
}

std::vector<std::pair<int, int>> MatchDescriptors(const Frame& a, const std::vector<int>& a_indices,
                                                  const Frame& b, const std::vector<int>& b_indices,
                                                  int max_distance, double ratio,
                                                  bool check_orientation) {
  std::vector<std::pair<int, int>> result;
  if (a_indices.empty() || b_indices.size() < 2) return result;
  cv::Mat query(static_cast<int>(a_indices.size()), 32, CV_8U);
  cv::Mat train(static_cast<int>(b_indices.size()), 32, CV_8U);
  for (size_t i = 0; i < a_indices.size(); ++i)
    a.descriptor(a_indices[i]).copyTo(query.row(static_cast<int>(i)));
  for (size_t j = 0; j < b_indices.size(); ++j)
    b.descriptor(b_indices[j]).copyTo(train.row(static_cast<int>(j)));
  cv::BFMatcher matcher(cv::NORM_HAMMING, false);
  std::vector<std::vector<cv::DMatch>> knn;
  matcher.knnMatch(query, train, knn, 2);
  // Best query per train keypoint.
  std::vector<int> query_of_train(b_indices.size(), -1);
  std::vector<float> dist_of_train(b_indices.size(), std::numeric_limits<float>::max());
  for (const auto& m : knn) {
    if (m.size() < 2) continue;
    if (m[0].distance > max_distance || m[0].distance >= ratio * m[1].distance) continue;
    const int t = m[0].trainIdx;
    if (m[0].distance < dist_of_train[t]) {
      dist_of_train[t] = m[0].distance;
      query_of_train[t] = m[0].queryIdx;
    }
  }
  std::vector<int> b_of_a(a_indices.size(), -1);
  for (size_t t = 0; t < b_indices.size(); ++t)
    if (query_of_train[t] >= 0) b_of_a[query_of_train[t]] = static_cast<int>(t);
  RotationConsistency rotation;
  int count = 0;
  for (size_t q = 0; q < a_indices.size(); ++q) {
    if (b_of_a[q] < 0) continue;
    ++count;
    if (check_orientation)
      rotation.Add(a.keypoint(a_indices[q]).angle, b.keypoint(b_indices[b_of_a[q]]).angle,
                   static_cast<int>(q));
  }
  if (check_orientation) DropRejected(rotation, &b_of_a, &count);
  for (size_t q = 0; q < a_indices.size(); ++q)
    if (b_of_a[q] >= 0) result.emplace_back(a_indices[q], b_indices[b_of_a[q]]);
  return result;
}

std::vector<std::pair<int, int>> SearchForTriangulation(const Frame& f1, const SE3& cam1_from_world,
                                                        const std::vector<uint8_t>& free1,
                                                        const Frame& f2, const SE3& cam2_from_world,
                                                        const std::vector<uint8_t>& free2) {
  const PinholeCamera& cam = f1.rig().left;
  const PinholeCamera& cam2 = f2.rig().left;
  const SE3 cam2_from_cam1 = cam2_from_world * cam1_from_world.inverse();
  const Eigen::Matrix3d R21 = cam2_from_cam1.linear();
  const Eigen::Vector3d t21 = cam2_from_cam1.translation();
  Eigen::Matrix3d K1, K2;
  K1 << cam.fx, 0, cam.cx, 0, cam.fy, cam.cy, 0, 0, 1;
  K2 << cam2.fx, 0, cam2.cx, 0, cam2.fy, cam2.cy, 0, 0, 1;
  // x2^T F21 x1 = 0.
  const Eigen::Matrix3d F21 = K2.inverse().transpose() * Skew(t21) * R21 * K1.inverse();
  // Epipole in image 2: the projection of camera 1's centre.
  const Eigen::Vector3d c1_in_cam2 = t21;
  const bool epipole_valid = c1_in_cam2.z() > 1e-9;
  const Eigen::Vector2d epipole =
      epipole_valid ? cam2.Project(c1_in_cam2) : Eigen::Vector2d(1e12, 1e12);

  const ScalePyramid& scale2 = f2.scale();
  std::vector<int> idx2;
  std::vector<double> u2, v2, line_th2;  // line_th2: squared epipolar-distance bound
  for (int j = 0; j < f2.size(); ++j) {
    if (!free2[j]) continue;
    idx2.push_back(j);
    u2.push_back(f2.keypoint(j).pt.x);
    v2.push_back(f2.keypoint(j).pt.y);
    line_th2.push_back(3.84 * scale2.level_sigma2[f2.keypoint(j).octave]);
  }
  std::vector<int> match_of_2(f2.size(), -1);
  std::vector<int> dist_of_2(f2.size(), std::numeric_limits<int>::max());
  for (int i = 0; i < f1.size(); ++i) {
    if (!free1[i]) continue;
    const Eigen::Vector3d x1(f1.keypoint(i).pt.x, f1.keypoint(i).pt.y, 1.0);
    const Eigen::Vector3d line = F21 * x1;
    const double norm2 = line.x() * line.x() + line.y() * line.y();
    if (norm2 <= 0) continue;
    const cv::Mat d1 = f1.descriptor(i);
    NearestTwo near;
    const double a = line.x(), b = line.y(), c = line.z();
    for (size_t k = 0; k < idx2.size(); ++k) {
      const double num = a * u2[k] + b * v2[k] + c;
      if (num * num >= line_th2[k] * norm2) continue;
      const int j = idx2[k];
      const int oct = f2.keypoint(j).octave;
      if (!f2.has_stereo(j)) {
        const double ex = epipole.x() - u2[k], ey = epipole.y() - v2[k];
        if (ex * ex + ey * ey < 100.0 * scale2.scale_factors[oct]) continue;
      }
      near.Add(DescriptorDistance(d1, f2.descriptor(j)), j);
    }
    const int best = near.nearest, best_j = near.nearest_index;
    if (best_j < 0 || best > kDescriptorDistanceLow || best >= 0.9 * near.second) continue;
    if (best < dist_of_2[best_j]) {
      dist_of_2[best_j] = best;
      match_of_2[best_j] = i;
    }
  }
  std::vector<int> match_of_1(f1.size(), -1);
  for (int j = 0; j < f2.size(); ++j)
    if (match_of_2[j] >= 0) match_of_1[match_of_2[j]] = j;
  RotationConsistency rotation;
  int count = 0;
  for (int i = 0; i < f1.size(); ++i) {
    if (match_of_1[i] < 0) continue;
    ++count;
    rotation.Add(f1.keypoint(i).angle, f2.keypoint(match_of_1[i]).angle, i);
  }
  DropRejected(rotation, &match_of_1, &count);
  std::vector<std::pair<int, int>> result;
  for (int i = 0; i < f1.size(); ++i)
    if (match_of_1[i] >= 0) result.emplace_back(i, match_of_1[i]);
  return result;
}

std::vector<std::pair<int, int>> FuseByProjection(const Frame& frame, const SE3& cam_from_world,
                                                  const std::vector<FuseCandidate>& candidates,
                                                  double radius_factor) {
  std::vector<std::pair<int, int>> result;
  const StereoRig& rig = frame.rig();
  const ScalePyramid& scale = frame.scale();
  const Eigen::Vector3d centre = cam_from_world.inverse().translation();
  for (size_t c = 0; c < candidates.size(); ++c) {
    const FuseCandidate& cand = candidates[c];
    const Eigen::Vector3d p_in_cam = cam_from_world * cand.p_in_world;
    if (p_in_cam.z() <= 0) continue;
    const Eigen::Vector2d uv = rig.left.Project(p_in_cam);
    if (!rig.left.InImage(uv)) continue;
    const Eigen::Vector3d ray = cand.p_in_world - centre;
    const double distance = ray.norm();
    if (distance < 0.8 * cand.min_distance_m || distance > 1.2 * cand.max_distance_m) continue;
    if (ray.dot(cand.normal) < 0.5 * distance) continue;
    const int level = scale.PredictLevel(distance, cand.max_distance_m);
    const double radius = radius_factor * scale.scale_factors[level];
    const std::vector<int> indices = frame.FeaturesInArea(uv.x(), uv.y(), radius);
    const double u_right = rig.IsStereo() ? rig.ProjectRightX(p_in_cam) : -1;
    int best = std::numeric_limits<int>::max(), best_idx = -1;
    for (int i : indices) {
      const int oct = frame.octave(i);
      if (oct < level - 1 || oct > level) continue;
      const double ex = uv.x() - frame.keypoint(i).pt.x, ey = uv.y() - frame.keypoint(i).pt.y;
      double e2 = ex * ex + ey * ey;
      double chi2 = kChi2Mono;
      if (rig.IsStereo() && frame.u_right_px(i) > 0) {
        const double er = u_right - frame.u_right_px(i);
        e2 += er * er;
        chi2 = kChi2Stereo;
      }
      if (e2 * scale.inv_level_sigma2[oct] > chi2) continue;
      const int d = DescriptorDistance(cand.descriptor, frame.descriptor(i));
      if (d < best) {
        best = d;
        best_idx = i;
      }
    }
    if (best_idx >= 0 && best <= kDescriptorDistanceLow)
      result.emplace_back(static_cast<int>(c), best_idx);
  }
  return result;
}

}  // namespace pcr
