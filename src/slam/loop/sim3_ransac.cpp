#include "slam/loop/sim3_ransac.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <random>

#include "slam/common/error.h"

namespace pcr {
namespace {

bool Usable(const Sim3Correspondence& m) {
  return m.p_in_cam1.allFinite() && m.p_in_cam2.allFinite() && m.uv1_px.allFinite() &&
         m.uv2_px.allFinite() && std::isfinite(m.sigma2_1) && m.sigma2_1 > 0 &&
         std::isfinite(m.sigma2_2) && m.sigma2_2 > 0;
}

// Squared pixel error of p_in_cam against uv_px; +infinity behind the camera.
double SquaredError(const PinholeCamera& camera, const Eigen::Vector3d& p_in_cam,
                    const Eigen::Vector2d& uv_px) {
  if (!(p_in_cam.z() > 0)) return INFINITY;
  return (uv_px - camera.Project(p_in_cam)).squaredNorm();
}

// Hypotheses needed for the probability with inlier ratio w and samples of 3.
int RequiredIterations(double probability, double w, int max_iterations) {
  const double w3 = w * w * w;
  if (w3 >= 1.0) return 1;
  if (!(w3 > 0)) return max_iterations;
  const double needed = std::ceil(std::log(1.0 - probability) / std::log(1.0 - w3));
  if (!std::isfinite(needed) || needed >= max_iterations) return max_iterations;
  return std::max(1, static_cast<int>(needed));
}

}  // namespace

bool Sim3RansacOptions::IsValid(std::string* why) const {
  auto fail = [&](const char* message) {
    if (why) *why = message;
    return false;
  };
  if (!(probability > 0 && probability < 1)) return fail("probability must be in (0, 1)");
  if (min_inliers < 3) return fail("min_inliers must be >= 3");
  if (max_iterations < 1) return fail("max_iterations must be >= 1");
  if (!std::isfinite(chi2_threshold) || !(chi2_threshold > 0))
    return fail("chi2_threshold must be finite and > 0");
  return true;
}

int CountSim3Inliers(const PinholeCamera& camera, const std::vector<Sim3Correspondence>& matches,
                     const Sim3& cam1_from_cam2, double chi2_threshold,
                     std::vector<bool>* inliers) {
  const Sim3 cam2_from_cam1 = cam1_from_cam2.Inverse();
  inliers->assign(matches.size(), false);
  int count = 0;
  for (size_t i = 0; i < matches.size(); ++i) {
    const Sim3Correspondence& m = matches[i];
    if (!Usable(m)) continue;
    const double e1 = SquaredError(camera, cam1_from_cam2.Map(m.p_in_cam2), m.uv1_px);
    const double e2 = SquaredError(camera, cam2_from_cam1.Map(m.p_in_cam1), m.uv2_px);
    if (e1 < chi2_threshold * m.sigma2_1 && e2 < chi2_threshold * m.sigma2_2) {
      (*inliers)[i] = true;
      ++count;
    }
  }
  return count;
}

Sim3RansacResult EstimateSim3Ransac(const PinholeCamera& camera,
                                    const std::vector<Sim3Correspondence>& matches,
                                    const Sim3RansacOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw ConfigError("Sim3RansacOptions: " + why);
  Sim3RansacResult result;
  result.inliers.assign(matches.size(), false);

  std::vector<int> usable;
  for (size_t i = 0; i < matches.size(); ++i)
    if (Usable(matches[i])) usable.push_back(static_cast<int>(i));
  const int n = static_cast<int>(usable.size());
  if (n < std::max(3, options.min_inliers)) return result;

  std::mt19937_64 rng(options.seed);
  // Modulo draws: the sequence depends on mt19937_64 alone (portable across standard libraries).
  auto draw = [&](int bound) { return static_cast<int>(rng() % static_cast<uint64_t>(bound)); };

  int best_count = 0;
  Sim3 best;
  std::vector<bool> flags;
  int needed = RequiredIterations(options.probability, static_cast<double>(options.min_inliers) / n,
                                  options.max_iterations);
  std::vector<Eigen::Vector3d> sample1(3), sample2(3);
  while (result.iterations < needed) {
    ++result.iterations;
    std::array<int, 3> picked{};
    for (int k = 0; k < 3; ++k) {
      int j;
      do {
        j = usable[draw(n)];
      } while (std::find(picked.begin(), picked.begin() + k, j) != picked.begin() + k);
      picked[k] = j;
      sample1[k] = matches[j].p_in_cam1;
      sample2[k] = matches[j].p_in_cam2;
    }
    const std::optional<Sim3> hypothesis = AlignPoints(sample1, sample2, options.fix_scale);
    if (!hypothesis) continue;
    const int count =
        CountSim3Inliers(camera, matches, *hypothesis, options.chi2_threshold, &flags);
    if (count > best_count) {
      best_count = count;
      best = *hypothesis;
      needed =
          std::min(needed, RequiredIterations(options.probability, static_cast<double>(count) / n,
                                              options.max_iterations));
    }
  }
  if (best_count < options.min_inliers) return result;

  // Refit on all inliers of the best hypothesis; keep the refit unless it loses inliers.
  CountSim3Inliers(camera, matches, best, options.chi2_threshold, &flags);
  std::vector<Eigen::Vector3d> inliers1, inliers2;
  for (size_t i = 0; i < matches.size(); ++i) {
    if (!flags[i]) continue;
    inliers1.push_back(matches[i].p_in_cam1);
    inliers2.push_back(matches[i].p_in_cam2);
  }
  if (const std::optional<Sim3> refit = AlignPoints(inliers1, inliers2, options.fix_scale)) {
    std::vector<bool> refit_flags;
    const int refit_count =
        CountSim3Inliers(camera, matches, *refit, options.chi2_threshold, &refit_flags);
    if (refit_count >= best_count) {
      best = *refit;
      best_count = refit_count;
      flags = refit_flags;
    }
  }
  result.success = best_count >= options.min_inliers;
  if (!result.success) return result;
  result.cam1_from_cam2 = best;
  result.inliers = flags;
  result.num_inliers = best_count;
  return result;
}

}  // namespace pcr
