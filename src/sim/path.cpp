#include "sim/path.h"

#include <cmath>
#include <numbers>
#include <stdexcept>

namespace pcr::sim {

Eigen::Vector2d PathPoint::Forward() const {
  return {std::sin(heading_rad), std::cos(heading_rad)};
}
Eigen::Vector2d PathPoint::Right() const { return {std::cos(heading_rad), -std::sin(heading_rad)}; }

Path::Path(const Eigen::Vector2d& start_xz, double start_heading_rad)
    : start_xz_(start_xz), start_heading_rad_(start_heading_rad) {}

PathPoint Path::EndPoint() const {
  if (pieces_.empty()) return {start_xz_, start_heading_rad_, 0};
  return Eval(pieces_.back(), pieces_.back().length_m);
}

void Path::AddLine(double length_m) {
  if (!(length_m > 0)) throw std::invalid_argument("Path::AddLine: length must be > 0");
  const PathPoint end = EndPoint();
  pieces_.push_back({end.xz, end.heading_rad, length_m, 0.0, length_m_});
  length_m_ += length_m;
}

void Path::AddArc(double radius_m, double angle_rad) {
  if (!(radius_m > 0) || angle_rad == 0)
    throw std::invalid_argument("Path::AddArc: radius must be > 0 and angle non-zero");
  const PathPoint end = EndPoint();
  const double curvature = (angle_rad > 0 ? 1.0 : -1.0) / radius_m;
  const double length_m = radius_m * std::abs(angle_rad);
  pieces_.push_back({end.xz, end.heading_rad, length_m, curvature, length_m_});
  length_m_ += length_m;
}

void Path::Close() {
  const PathPoint end = EndPoint();
  const double turn = std::remainder(end.heading_rad - start_heading_rad_, 2 * std::numbers::pi);
  if ((end.xz - start_xz_).norm() > 1e-3 || std::abs(turn) > 1e-6)
    throw std::invalid_argument("Path::Close: the path does not end at its start");
  closed_ = true;
}

PathPoint Path::Eval(const Piece& piece, double ds_m) {
  PathPoint p;
  p.curvature_per_m = piece.curvature_per_m;
  const double k = piece.curvature_per_m;
  const double h0 = piece.heading_rad;
  if (k == 0) {
    p.heading_rad = h0;
    p.xz = piece.start_xz + ds_m * Eigen::Vector2d(std::sin(h0), std::cos(h0));
  } else {
    const double h = h0 + k * ds_m;
    p.heading_rad = h;
    p.xz = piece.start_xz +
           Eigen::Vector2d(std::cos(h0) - std::cos(h), std::sin(h) - std::sin(h0)) / k;
  }
  return p;
}

PathPoint Path::At(double s_m) const {
  if (pieces_.empty()) {
    PathPoint p{start_xz_, start_heading_rad_, 0};
    p.xz += s_m * p.Forward();
    return p;
  }
  if (closed_) {
    s_m = std::fmod(s_m, length_m_);
    if (s_m < 0) s_m += length_m_;
  } else if (s_m < 0) {
    PathPoint p{pieces_.front().start_xz, pieces_.front().heading_rad, 0};
    p.xz += s_m * p.Forward();
    return p;
  } else if (s_m > length_m_) {
    PathPoint p = EndPoint();
    p.curvature_per_m = 0;
    p.xz += (s_m - length_m_) * p.Forward();
    return p;
  }
  // Binary search for the piece holding s_m.
  size_t lo = 0, hi = pieces_.size();
  while (hi - lo > 1) {
    const size_t mid = (lo + hi) / 2;
    if (pieces_[mid].s0_m <= s_m)
      lo = mid;
    else
      hi = mid;
  }
  return Eval(pieces_[lo], std::min(s_m - pieces_[lo].s0_m, pieces_[lo].length_m));
}

Path Path::Offset(double right_m) const {
  const PathPoint start{start_xz_, start_heading_rad_, 0};
  Path out(start_xz_ + right_m * start.Right(), start_heading_rad_);
  for (const Piece& piece : pieces_) {
    if (piece.curvature_per_m == 0) {
      out.AddLine(piece.length_m);
    } else {
      const double scale = 1.0 - piece.curvature_per_m * right_m;
      if (!(scale > 1e-6)) throw std::invalid_argument("Path::Offset: an arc collapses");
      const double radius = std::abs(1.0 / piece.curvature_per_m) * scale;
      const double angle = piece.curvature_per_m * piece.length_m;
      out.AddArc(radius, angle);
    }
  }
  if (closed_) out.Close();
  return out;
}

Path Path::Reversed() const {
  const PathPoint end = EndPoint();
  Path out(end.xz, end.heading_rad + std::numbers::pi);
  for (auto it = pieces_.rbegin(); it != pieces_.rend(); ++it) {
    if (it->curvature_per_m == 0)
      out.AddLine(it->length_m);
    else
      out.AddArc(std::abs(1.0 / it->curvature_per_m), -it->curvature_per_m * it->length_m);
  }
  if (closed_) out.Close();
  return out;
}

double Path::ClosestIn(const Eigen::Vector2d& p_xz, double lo_m, double hi_m) const {
  constexpr double kStep = 0.5;
  double best_s = lo_m;
  double best_d2 = (At(lo_m).xz - p_xz).squaredNorm();
  for (double s = lo_m + kStep; s <= hi_m; s += kStep) {
    const double d2 = (At(s).xz - p_xz).squaredNorm();
    if (d2 < best_d2) {
      best_d2 = d2;
      best_s = s;
    }
  }
  // Golden-section refinement around the best sample.
  double a = std::max(lo_m, best_s - kStep), b = std::min(hi_m, best_s + kStep);
  const double g = (std::sqrt(5.0) - 1) / 2;
  for (int i = 0; i < 40; ++i) {
    const double c = b - g * (b - a), d = a + g * (b - a);
    if ((At(c).xz - p_xz).squaredNorm() < (At(d).xz - p_xz).squaredNorm())
      b = d;
    else
      a = c;
  }
  return 0.5 * (a + b);
}

double Path::Closest(const Eigen::Vector2d& p_xz) const {
  return ClosestIn(p_xz, 0.0, std::max(length_m_, 0.0));
}

}  // namespace pcr::sim
