#pragma once
// Internal scene description of the synthetic world (src/sim only). The map frame has x right,
// y down, z forward, the road plane at y = 0 (so things above the road have y < 0).
#include <Eigen/Core>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

namespace pcr::sim {

// Street cross-section, metres from the centre line.
inline constexpr double kLaneWidthM = 3.5;      // one lane per direction
inline constexpr double kRoadHalfWidthM = 6.0;  // lanes + parking strip, up to the kerb
inline constexpr double kSidewalkOuterM = 9.0;  // sidewalk from the kerb to here
inline constexpr double kKerbHeightM = 0.15;

enum class Material : uint8_t {
  kFacade,
  kSidewalk,
  kPole,
  kSign,
  kCarBody,
  kCarCabin,
  kWheel,
  kLegs,
  kTorso,
  kHead,
  kBikeFrame,
  kBikeWheel,
  kClutter,  // bins, bollards, cabinets
  kHedge,
  kBalcony,
};

// An oriented box: p_parent = center + R_y(yaw) * p_local, |p_local| <= half_m per axis. Texture
// coordinates are taken in the box's own frame, so they stick to the box (and to its object).
struct BoxPrim {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  double yaw_rad = 0;  // local z axis = (sin yaw, 0, cos yaw) in the parent frame
  Eigen::Vector3d half_m = Eigen::Vector3d::Constant(0.5);
  Material material = Material::kFacade;
  uint16_t instance_id = 0;
  uint32_t seed = 0;
  float tone = 0.5f;              // base albedo in [0, 1]
  std::array<float, 12> param{};  // material parameters
};

// A straight street: centre line from start_xz along heading (forward (sin h, cos h)).
struct Street {
  Eigen::Vector2d start_xz = Eigen::Vector2d::Zero();
  double heading_rad = 0;
  double length_m = 0;

  Eigen::Vector2d Dir() const { return {std::sin(heading_rad), std::cos(heading_rad)}; }
  Eigen::Vector2d Right() const { return {std::cos(heading_rad), -std::sin(heading_rad)}; }
  // Along (s) and right (l) coordinates of a ground point.
  Eigen::Vector2d Local(const Eigen::Vector2d& p_xz) const {
    const Eigen::Vector2d d = p_xz - start_xz;
    return {d.dot(Dir()), d.dot(Right())};
  }
};

// A pedestrian crossing painted across a street: centre on the ground and the street heading.
struct Zebra {
  Eigen::Vector2d center_xz = Eigen::Vector2d::Zero();
  double heading_rad = 0;
};

// Everything painted on the road plane.
struct Ground {
  std::vector<Street> streets;
  std::vector<Zebra> zebras;
};

}  // namespace pcr::sim
