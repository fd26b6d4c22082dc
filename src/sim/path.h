#pragma once
// Planar paths on the ground of the synthetic world, parameterised by arc length. Coordinates are
// the map frame's (x, z) ground plane (map frame: x right, y down, z forward, road at y = 0).
// Heading psi: forward = (sin psi, cos psi) in (x, z), right = (cos psi, -sin psi); positive
// curvature turns right (psi grows).
#include <Eigen/Core>
#include <vector>

namespace pcr::sim {

struct PathPoint {
  Eigen::Vector2d xz = Eigen::Vector2d::Zero();  // metres
  double heading_rad = 0;
  double curvature_per_m = 0;  // 0 on straight pieces

  Eigen::Vector2d Forward() const;
  Eigen::Vector2d Right() const;
};

// A chain of straight lines and circular arcs. An open path is extended straight beyond both
// ends; a closed path wraps its arc length.
class Path {
 public:
  Path() = default;
  Path(const Eigen::Vector2d& start_xz, double start_heading_rad);

  void AddLine(double length_m);
  // radius_m > 0; angle_rad > 0 turns right, < 0 turns left.
  void AddArc(double radius_m, double angle_rad);
  // Marks the path closed; its end must meet its start (within 1 mm, same heading modulo 2 pi).
  void Close();

  double Length() const { return length_m_; }
  bool closed() const { return closed_; }
  bool empty() const { return pieces_.empty(); }
  PathPoint At(double s_m) const;

  // The path shifted by right_m to the right (negative: left). Arcs keep their centres, so an
  // offset path has its own arc length. Throws std::invalid_argument if an arc would collapse.
  Path Offset(double right_m) const;
  // The same curve driven the other way.
  Path Reversed() const;
  // Arc length of the point of the path nearest to p_xz (searched within the path's length).
  double Closest(const Eigen::Vector2d& p_xz) const;
  // Arc length of the nearest point in [lo_m, hi_m].
  double ClosestIn(const Eigen::Vector2d& p_xz, double lo_m, double hi_m) const;

 private:
  struct Piece {
    Eigen::Vector2d start_xz;
    double heading_rad;
    double length_m;
    double curvature_per_m;
    double s0_m;
  };
  static PathPoint Eval(const Piece& piece, double ds_m);
  PathPoint EndPoint() const;

  Eigen::Vector2d start_xz_ = Eigen::Vector2d::Zero();
  double start_heading_rad_ = 0;
  std::vector<Piece> pieces_;
  double length_m_ = 0;
  bool closed_ = false;
};

}  // namespace pcr::sim
