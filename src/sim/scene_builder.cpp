#include "sim/scene_builder.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "sim/texture.h"

namespace pcr::sim {

uint64_t Rng::Next() {
  uint64_t z = (state_ += 0x9e3779b97f4a7c15ULL);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

double Rng::Uniform(double lo, double hi) {
  return lo + (hi - lo) * static_cast<double>(Next() >> 11) * (1.0 / 9007199254740992.0);
}

double Motion::LateralAt(double t_s) const {
  const double span = lat_hi_m - lat_lo_m;
  if (span <= 0) return lat_lo_m;
  double u = std::fmod(u0_m + speed_mps * t_s, 2 * span);
  if (u < 0) u += 2 * span;
  return u < span ? lat_lo_m + u : lat_hi_m - (u - span);
}

void Motion::At(double t_s, Eigen::Vector2d* xz_out, double* heading_out) const {
  switch (kind) {
    case Kind::kStatic:
      *xz_out = xz;
      *heading_out = heading_rad;
      return;
    case Kind::kFollowPath: {
      const PathPoint p = path.At(s0_m + speed_mps * t_s);
      *xz_out = p.xz;
      *heading_out = p.heading_rad;
      return;
    }
    case Kind::kCrossing: {
      const double span = lat_hi_m - lat_lo_m;
      double u = std::fmod(u0_m + speed_mps * t_s, 2 * span);
      if (u < 0) u += 2 * span;
      const bool to_right = u < span;
      const Eigen::Vector2d right(std::cos(heading_rad), -std::sin(heading_rad));
      *xz_out = xz + LateralAt(t_s) * right;
      *heading_out = heading_rad + (to_right ? 0.5 : -0.5) * std::numbers::pi;
      return;
    }
  }
}

Eigen::Isometry3d GroundPose(const Eigen::Vector2d& xz, double heading_rad) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = Eigen::AngleAxisd(heading_rad, Eigen::Vector3d::UnitY()).toRotationMatrix();
  pose.translation() = Eigen::Vector3d(xz.x(), 0.0, xz.y());
  return pose;
}

namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kCornerRadiusM = 12.0;  // ego lane radius at the loop's corners
constexpr double kStreetBehindM = 60.0;  // straight street length behind the start

// Random streams (independent, so e.g. the mover count does not change the buildings).
enum Stream : uint64_t {
  kStreamBuildings = 1,
  kStreamMovers = 2,
  kStreamParked = 3,
  kStreamPoles = 4,
  kStreamMisc = 5
};
Rng MakeRng(uint64_t seed, Stream stream) {
  Rng mixer(seed * 0x2545f4914f6cdd1dULL + stream * 0x9e3779b97f4a7c15ULL);
  return Rng(mixer.Next());
}

// Oriented rectangle on the ground: half_lat across, half_along along heading.
struct Rect2 {
  Eigen::Vector2d c;
  double heading;
  double half_lat, half_along;
  Eigen::Vector2d Along() const { return {std::sin(heading), std::cos(heading)}; }
  Eigen::Vector2d Lat() const { return {std::cos(heading), -std::sin(heading)}; }
};

// True when a and b overlap by more than tol (separating axis test).
bool Overlaps(const Rect2& a, const Rect2& b, double tol) {
  const Eigen::Vector2d axes[4] = {a.Along(), a.Lat(), b.Along(), b.Lat()};
  const Eigen::Vector2d d = b.c - a.c;
  for (const auto& n : axes) {
    const double ra =
        a.half_lat * std::abs(a.Lat().dot(n)) + a.half_along * std::abs(a.Along().dot(n));
    const double rb =
        b.half_lat * std::abs(b.Lat().dot(n)) + b.half_along * std::abs(b.Along().dot(n));
    if (std::abs(d.dot(n)) - (ra + rb) > -tol) return false;
  }
  return true;
}

double PointRectDistance(const Eigen::Vector2d& p, const Rect2& r) {
  const Eigen::Vector2d d = p - r.c;
  const double dl = std::max(0.0, std::abs(d.dot(r.Lat())) - r.half_lat);
  const double da = std::max(0.0, std::abs(d.dot(r.Along())) - r.half_along);
  return std::hypot(dl, da);
}

Rect2 StreetRect(const Street& s, double half_width) {
  return {s.start_xz + 0.5 * s.length_m * s.Dir(), s.heading_rad, half_width, 0.5 * s.length_m};
}

Rect2 Footprint(const BoxPrim& b) {
  return {{b.center.x(), b.center.z()}, b.yaw_rad, b.half_m.x(), b.half_m.z()};
}

// Box standing on the ground: lateral/along relative to a street.
BoxPrim StreetBox(const Street& street, double s_m, double lat_m, double half_lat, double height,
                  double half_along, double bottom_m = 0.0) {
  BoxPrim b;
  const Eigen::Vector2d p = street.start_xz + s_m * street.Dir() + lat_m * street.Right();
  b.center = Eigen::Vector3d(p.x(), -(bottom_m + 0.5 * height), p.y());
  b.yaw_rad = street.heading_rad;
  b.half_m = Eigen::Vector3d(half_lat, 0.5 * height, half_along);
  return b;
}

bool IntrudesStreets(const Rect2& r, const std::vector<Street>& streets, double half_width,
                     double tol, int skip = -1) {
  for (size_t i = 0; i < streets.size(); ++i) {
    if (static_cast<int>(i) == skip) continue;
    if (Overlaps(r, StreetRect(streets[i], half_width), tol)) return true;
  }
  return false;
}

void SetFacade(BoxPrim* b, Rng& rng) {
  b->material = Material::kFacade;
  b->seed = rng.U32();
  b->tone = static_cast<float>(rng.Uniform(0.42, 0.8));
  const double floor_h = rng.Uniform(2.9, 3.5);
  const double period = rng.Uniform(2.3, 3.6);
  b->param[0] = static_cast<float>(floor_h);
  b->param[1] = static_cast<float>(rng.Uniform(3.6, 4.5));
  b->param[2] = static_cast<float>(period);
  b->param[3] = static_cast<float>(rng.Uniform(0.9, std::min(1.6, period - 0.6)));
  b->param[4] = static_cast<float>(rng.Uniform(1.2, std::min(1.7, floor_h - 1.3)));
  b->param[5] = static_cast<float>(rng.Uniform(0, period));
  b->param[6] = static_cast<float>(static_cast<int>(rng.Uniform(0, 3)));
  b->param[7] = static_cast<float>((rng.Chance(0.5) ? 1 : 0) | (rng.Chance(0.6) ? 2 : 0));
  b->param[8] = static_cast<float>(rng.Uniform(0.45, 0.85));   // plinth height
  b->param[9] = static_cast<float>(rng.Uniform(0.25, 0.55));   // plinth tone
  b->param[10] = static_cast<float>(rng.Uniform(0.15, 0.25));  // ground-floor glass tone
}

// Balconies in front of some upper-floor windows of a facade that starts at s_start along the
// street, with its street-facing face at lateral_m.
void AddBalconies(const Street& street, double s_start, double lateral_m, int side, double length,
                  double height, const BoxPrim& building, uint32_t seed,
                  std::vector<BoxPrim>* out) {
  const double floor_h = building.param[0], ground_h = building.param[1];
  const double period = building.param[2], win_w = building.param[3], offset = building.param[5];
  constexpr double kDepth = 1.0, kRail = 1.0;
  const float tone = static_cast<float>(0.3 + 0.5 * tex::Unit(tex::Hash1(1, seed)));
  for (int floor = 1; ground_h + floor * floor_h + kRail < height - 0.8; ++floor) {
    for (int k = -1; offset + k * period < length; ++k) {
      const double a0 = offset + k * period - 0.35, a1 = offset + k * period + win_w + 0.35;
      if (a0 < 0.3 || a1 > length - 0.3) continue;
      const uint32_t h = tex::Hash2(k, floor, seed);
      if (tex::Unit(h) < 0.45) continue;
      BoxPrim b =
          StreetBox(street, s_start + 0.5 * (a0 + a1), lateral_m - side * 0.5 * kDepth,
                    0.5 * kDepth, kRail, 0.5 * (a1 - a0), ground_h + floor * floor_h - 0.15);
      b.material = Material::kBalcony;
      b.seed = h;
      b.tone = tone;
      out->push_back(b);
    }
  }
}

void AddBuildings(const std::vector<Street>& streets, Rng& rng, std::vector<BoxPrim>* out) {
  for (size_t si = 0; si < streets.size(); ++si) {
    const Street& street = streets[si];
    for (int side = -1; side <= 1; side += 2) {
      double s = -5.0;
      while (s < street.length_m + 5.0) {
        const double length = rng.Uniform(8, 22);
        const double setback = rng.Chance(0.4) ? rng.Uniform(0.5, 3.0) : 0.0;
        const double depth = rng.Uniform(9, 15);
        const double height = rng.Uniform(7, 22);
        BoxPrim b =
            StreetBox(street, s + 0.5 * length, side * (kSidewalkOuterM + setback + 0.5 * depth),
                      0.5 * depth, height, 0.5 * length);
        SetFacade(&b, rng);
        const bool balconies = rng.Chance(0.4);
        if (!IntrudesStreets(Footprint(b), streets, kSidewalkOuterM, 0.05)) {
          out->push_back(b);
          if (balconies)
            AddBalconies(street, s, side * (kSidewalkOuterM + setback), side, length, height, b,
                         rng.U32(), out);
        }
        s += length;
        if (rng.Chance(0.25)) {  // a gap, with a building further back
          const double gap = rng.Uniform(2.5, 8.0);
          const double back_depth = rng.Uniform(8, 14);
          BoxPrim back =
              StreetBox(street, s + 0.5 * gap, side * (kSidewalkOuterM + 18 + 0.5 * back_depth),
                        0.5 * back_depth, rng.Uniform(10, 28), 0.5 * gap + 4.0);
          SetFacade(&back, rng);
          if (!IntrudesStreets(Footprint(back), streets, kSidewalkOuterM, 0.05))
            out->push_back(back);
          s += gap;
        }
      }
    }
    // Walls closing the view at both ends of the street.
    for (int end = 0; end < 2; ++end) {
      const double s_wall =
          end == 0 ? -kSidewalkOuterM - 6.0 : street.length_m + kSidewalkOuterM + 6.0;
      BoxPrim wall =
          StreetBox(street, s_wall, 0.0, kSidewalkOuterM + 25.0, rng.Uniform(14, 26), 5.0);
      SetFacade(&wall, rng);
      wall.yaw_rad += 0.5 * kPi;  // facades along the wall's long side face the street
      std::swap(wall.half_m.x(), wall.half_m.z());
      out->push_back(wall);
    }
  }
}

void AddSidewalks(const std::vector<Street>& streets, Rng& rng, std::vector<BoxPrim>* out) {
  constexpr double kStep = 1.0, kMaxPiece = 25.0;
  const double half_lat = 0.5 * (kSidewalkOuterM - kRoadHalfWidthM);
  const double lat_mid = 0.5 * (kSidewalkOuterM + kRoadHalfWidthM);
  for (size_t si = 0; si < streets.size(); ++si) {
    const Street& street = streets[si];
    for (int side = -1; side <= 1; side += 2) {
      double run_start = -1;
      auto flush = [&](double run_end) {
        if (run_start < 0 || run_end <= run_start) return;
        BoxPrim b = StreetBox(street, 0.5 * (run_start + run_end), side * lat_mid, half_lat,
                              kKerbHeightM, 0.5 * (run_end - run_start));
        b.material = Material::kSidewalk;
        b.seed = rng.U32();
        b.tone = static_cast<float>(rng.Uniform(0.5, 0.6));
        out->push_back(b);
      };
      for (double s = 0; s + kStep <= street.length_m + 1e-9; s += kStep) {
        const Rect2 piece{
            street.start_xz + (s + 0.5 * kStep) * street.Dir() + side * lat_mid * street.Right(),
            street.heading_rad, half_lat, 0.5 * kStep};
        const bool keep =
            !IntrudesStreets(piece, streets, kRoadHalfWidthM, 0.01, static_cast<int>(si));
        if (keep && run_start < 0) run_start = s;
        if (!keep && run_start >= 0) {
          flush(s);
          run_start = -1;
        }
        if (keep && s + kStep - run_start >= kMaxPiece - 1e-9) {
          flush(s + kStep);
          run_start = -1;
        }
      }
      flush(std::floor(street.length_m / kStep) * kStep);
    }
  }
}

void AddPoles(const std::vector<Street>& streets, Rng& rng, std::vector<BoxPrim>* out) {
  for (const Street& street : streets) {
    for (int side = -1; side <= 1; side += 2) {
      for (double s = rng.Uniform(5, 20); s < street.length_m - 2; s += rng.Uniform(18, 32)) {
        const double lat = side * (kRoadHalfWidthM + 0.35);
        const double height = rng.Uniform(4.5, 7.0);
        BoxPrim pole = StreetBox(street, s, lat, 0.07, height, 0.07, kKerbHeightM);
        if (IntrudesStreets({{pole.center.x(), pole.center.z()}, pole.yaw_rad, 0.6, 0.6}, streets,
                            kRoadHalfWidthM, 0.0))
          continue;
        pole.material = Material::kPole;
        pole.seed = rng.U32();
        pole.tone = static_cast<float>(rng.Uniform(0.35, 0.6));
        out->push_back(pole);
        if (rng.Chance(0.5)) {  // lamp arm over the road
          BoxPrim arm =
              StreetBox(street, s, lat - side * 0.7, 0.7, 0.1, 0.08, kKerbHeightM + height - 0.3);
          arm.material = Material::kPole;
          arm.seed = rng.U32();
          arm.tone = pole.tone;
          out->push_back(arm);
        } else if (rng.Chance(0.7)) {  // a sign facing the traffic on this side
          BoxPrim sign = StreetBox(street, s + (side > 0 ? -0.1 : 0.1), lat, 0.32, 0.64, 0.02,
                                   kKerbHeightM + rng.Uniform(1.9, 2.6));
          sign.material = Material::kSign;
          sign.seed = rng.U32();
          sign.tone = static_cast<float>(rng.Uniform(0.15, 0.4));
          if (side > 0) sign.yaw_rad += kPi;
          out->push_back(sign);
        }
      }
    }
  }
}

// Bins, cabinets, bollards and hedges on the sidewalks (static background).
void AddClutter(const std::vector<Street>& streets, Rng& rng, std::vector<BoxPrim>* out) {
  auto add = [&](const Street& street, double s, double lat, double half_lat, double height,
                 double half_along, Material material, float tone) {
    BoxPrim b = StreetBox(street, s, lat, half_lat, height, half_along, kKerbHeightM);
    if (IntrudesStreets(Footprint(b), streets, kRoadHalfWidthM, 0.0)) return;
    b.material = material;
    b.seed = rng.U32();
    b.tone = tone;
    out->push_back(b);
  };
  for (const Street& street : streets) {
    for (int side = -1; side <= 1; side += 2) {
      for (double s = rng.Uniform(2, 8); s < street.length_m - 2; s += rng.Uniform(5, 13)) {
        const double pick = rng.Uniform(0, 1);
        if (pick < 0.4) {  // bin or cabinet by the facades
          const bool cabinet = rng.Chance(0.4);
          add(street, s, side * (kSidewalkOuterM - 0.45), cabinet ? 0.25 : 0.3,
              cabinet ? 1.3 : rng.Uniform(0.9, 1.2), cabinet ? 0.45 : 0.3, Material::kClutter,
              static_cast<float>(rng.Uniform(0.15, 0.8)));
        } else if (pick < 0.6) {  // a row of bollards along the kerb
          const float tone = static_cast<float>(rng.Uniform(0.3, 0.65));
          for (int k = 0; k < 5; ++k)
            add(street, s + 1.8 * k, side * (kRoadHalfWidthM + 0.3), 0.07, 0.9, 0.07,
                Material::kClutter, tone);
        } else if (pick < 0.8) {  // hedge in front of a facade
          add(street, s, side * (kSidewalkOuterM - 0.4), 0.35, rng.Uniform(0.7, 1.2),
              rng.Uniform(1.5, 4.0), Material::kHedge, static_cast<float>(rng.Uniform(0.25, 0.45)));
        }
      }
    }
  }
}

// ---- objects ----

BoxPrim Part(Material material, const Eigen::Vector3d& center, const Eigen::Vector3d& half,
             float tone, uint32_t seed, uint16_t id) {
  BoxPrim b;
  b.material = material;
  b.center = center;
  b.half_m = half;
  b.tone = tone;
  b.seed = seed;
  b.instance_id = id;
  return b;
}

double CarTone(Rng& rng) {
  const double pick = rng.Uniform(0, 1);
  if (pick < 0.3) return rng.Uniform(0.08, 0.2);
  if (pick < 0.7) return rng.Uniform(0.3, 0.5);
  return rng.Uniform(0.55, 0.65);
}

std::vector<BoxPrim> MakeCar(Rng& rng, uint16_t id) {
  const double len = rng.Uniform(3.9, 4.7), wid = rng.Uniform(1.7, 1.85);
  const double height = rng.Uniform(1.4, 1.55);
  const float tone = static_cast<float>(CarTone(rng));
  const double body_lo = 0.3, body_hi = 0.92;
  std::vector<BoxPrim> parts;
  parts.push_back(Part(Material::kCarBody, {0, -0.5 * (body_lo + body_hi), 0},
                       {0.5 * wid, 0.5 * (body_hi - body_lo), 0.5 * len}, tone, rng.U32(), id));
  const double cabin_h = height - body_hi;
  parts.push_back(Part(Material::kCarCabin, {0, -(body_hi + 0.5 * cabin_h), -0.06 * len},
                       {0.5 * wid - 0.07, 0.5 * cabin_h, 0.28 * len}, tone, rng.U32(), id));
  const double r = 0.32;
  for (int sx = -1; sx <= 1; sx += 2)
    for (int sz = -1; sz <= 1; sz += 2)
      parts.push_back(Part(Material::kWheel, {sx * (0.5 * wid - 0.08), -r, sz * (0.5 * len - 0.8)},
                           {0.11, r, r}, 0.07f, rng.U32(), id));
  return parts;
}

// A delivery van (a "car" to a detector): one tall body box with a short cabin in front.
std::vector<BoxPrim> MakeVan(Rng& rng, uint16_t id) {
  const double len = rng.Uniform(5.0, 5.6), wid = rng.Uniform(1.95, 2.1);
  const double height = rng.Uniform(2.3, 2.6);
  const float tone = static_cast<float>(CarTone(rng));
  const double body_lo = 0.35;
  std::vector<BoxPrim> parts;
  parts.push_back(Part(Material::kCarBody, {0, -0.5 * (body_lo + height), -0.1 * len},
                       {0.5 * wid, 0.5 * (height - body_lo), 0.4 * len}, tone, rng.U32(), id));
  const double cabin_h = 0.75 * (height - body_lo);
  parts.push_back(Part(Material::kCarCabin, {0, -(body_lo + 0.5 * cabin_h), 0.4 * len},
                       {0.5 * wid - 0.05, 0.5 * cabin_h, 0.1 * len}, tone, rng.U32(), id));
  const double r = 0.35;
  for (int sx = -1; sx <= 1; sx += 2)
    for (int sz = -1; sz <= 1; sz += 2)
      parts.push_back(Part(Material::kWheel, {sx * (0.5 * wid - 0.08), -r, sz * (0.5 * len - 0.9)},
                           {0.12, r, r}, 0.07f, rng.U32(), id));
  return parts;
}

void AddPerson(Rng& rng, uint16_t id, double hip_m, double z_lean, std::vector<BoxPrim>* parts,
               bool riding) {
  const double height = rng.Uniform(1.6, 1.9);
  const double legs_lo = riding ? hip_m - 0.45 : 0.0;
  const double legs_hi = riding ? hip_m : 0.47 * height;
  const double torso_hi = legs_hi + 0.38 * height;
  const double head_hi = torso_hi + 0.14 * height;
  const uint32_t seed = rng.U32();
  parts->push_back(Part(Material::kLegs, {0, -0.5 * (legs_lo + legs_hi), 0},
                        {0.17, 0.5 * (legs_hi - legs_lo), riding ? 0.16 : 0.12},
                        static_cast<float>(rng.Uniform(0.08, 0.45)), seed, id));
  parts->push_back(Part(Material::kTorso, {0, -0.5 * (legs_hi + torso_hi), z_lean},
                        {0.23, 0.5 * (torso_hi - legs_hi), 0.13},
                        static_cast<float>(rng.Uniform(0.1, 0.9)), seed + 1, id));
  BoxPrim head = Part(Material::kHead, {0, -0.5 * (torso_hi + head_hi), 2 * z_lean},
                      {0.1, 0.5 * (head_hi - torso_hi), 0.11},
                      static_cast<float>(rng.Uniform(0.45, 0.7)), seed + 2, id);
  head.param[0] = static_cast<float>(rng.Uniform(0, 1));
  parts->push_back(head);
}

std::vector<BoxPrim> MakeBicycle(Rng& rng, uint16_t id) {
  std::vector<BoxPrim> parts;
  const float tone = static_cast<float>(rng.Uniform(0.2, 0.85));
  for (int sz = -1; sz <= 1; sz += 2)
    parts.push_back(Part(Material::kBikeWheel, {0, -0.34, sz * 0.52}, {0.03, 0.34, 0.34}, 0.08f,
                         rng.U32(), id));
  parts.push_back(Part(Material::kBikeFrame, {0, -0.62, 0}, {0.04, 0.2, 0.5}, tone, rng.U32(), id));
  parts.push_back(
      Part(Material::kBikeFrame, {0, -1.0, 0.45}, {0.3, 0.025, 0.025}, 0.1f, rng.U32(), id));
  return parts;
}

Eigen::Vector3d PartsSize(const std::vector<BoxPrim>& parts) {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e9), hi = -lo;
  for (const BoxPrim& p : parts) {
    lo = lo.cwiseMin(p.center - p.half_m);
    hi = hi.cwiseMax(p.center + p.half_m);
  }
  return hi - lo;
}

enum class MoverType {
  kCarAhead,
  kCarOncoming,
  kPersonCrossing,
  kCyclistCrossing,
  kPersonWalking,
  kCyclistOncoming
};

constexpr MoverType kMoverCycle[] = {MoverType::kCarAhead,        MoverType::kCarOncoming,
                                     MoverType::kPersonCrossing,  MoverType::kCyclistCrossing,
                                     MoverType::kCarOncoming,     MoverType::kPersonWalking,
                                     MoverType::kCyclistOncoming, MoverType::kPersonCrossing,
                                     MoverType::kCarOncoming,     MoverType::kPersonWalking};

struct CrossingLine {
  Eigen::Vector2d xz;
  double heading_rad;
};

// A vehicle driving along a lane of the ego's street (the ego itself included).
struct LaneUser {
  int lane;              // 0 ego lane, 1 oncoming lane, 2 oncoming cyclist strip
  double lateral_m;      // lane centre, to the right of the ego lane
  Motion motion;         // kFollowPath
  double half_length_m;  // along its path
  double half_width_m;
};

struct BuildContext {
  const SynthOptions& options;
  Scene* scene;
  double duration_s;
  std::vector<CrossingLine> crossings;
  std::vector<LaneUser> lane_users;
};

double EgoS(const BuildContext& ctx, double t_s) {
  return ctx.scene->ego_s0_m + ctx.options.speed_mps * t_s;
}

// Arc length on `path` where it passes the ego's position at time t_s (plus ahead_m along the
// ego's lane and lateral_m to its right).
double MeetingS(const BuildContext& ctx, const Path& path, double t_s, double ahead_m,
                double lateral_m) {
  const PathPoint ego = ctx.scene->ego_path.At(EgoS(ctx, t_s) + ahead_m);
  const Eigen::Vector2d p = ego.xz + lateral_m * ego.Right();
  if (path.closed()) return path.Closest(p);
  return path.ClosestIn(p, -200.0, path.Length() + 200.0);
}

// Pushes s forward (on a closed route) until the ego lane is straight for +-12 m around it.
double StraightS(const Path& path, double s) {
  if (!path.closed()) return s;
  for (int i = 0; i < 400; ++i, s += 2.0)
    if (path.At(s - 12).curvature_per_m == 0 && path.At(s).curvature_per_m == 0 &&
        path.At(s + 12).curvature_per_m == 0)
      return s;
  return s;
}

// Gap along the path between two followers of the same lane path at time t_s.
double PathGap(const Motion& a, const Motion& b, double t_s) {
  double d = (a.s0_m + a.speed_mps * t_s) - (b.s0_m + b.speed_mps * t_s);
  if (a.path.closed()) d = std::remainder(d, a.path.Length());
  return std::abs(d);
}

// True when a new follower of `lane` keeps 7 m from the others in that lane during the run.
bool LaneIsFree(const BuildContext& ctx, int lane, const Motion& motion) {
  for (const LaneUser& other : ctx.lane_users) {
    if (other.lane != lane) continue;
    for (double t = -1.0; t <= ctx.duration_s + 1.0; t += 0.1)
      if (PathGap(motion, other.motion, t) < 7.0) return false;
  }
  return true;
}

// True when a crossing object keeps clear of every lane user as it drives over the crossing.
bool CrossingIsClear(const BuildContext& ctx, const Motion& crossing) {
  const Eigen::Vector2d right(std::cos(crossing.heading_rad), -std::sin(crossing.heading_rad));
  for (const LaneUser& user : ctx.lane_users) {
    if (user.motion.speed_mps <= 0) continue;
    const Path& path = user.motion.path;
    const Eigen::Vector2d p = crossing.xz + user.lateral_m * right;
    const double s_cross =
        path.closed() ? path.Closest(p) : path.ClosestIn(p, -200.0, path.Length() + 200.0);
    const double laps = path.closed() ? path.Length() : 1e18;
    const double window_s = (user.half_length_m + 1.0) / user.motion.speed_mps;
    for (int lap = -2; lap <= 2; ++lap) {
      const double t_pass = (s_cross + lap * laps - user.motion.s0_m) / user.motion.speed_mps;
      if (t_pass < -window_s - 1 || t_pass > ctx.duration_s + window_s + 1) continue;
      for (double t = t_pass - window_s; t <= t_pass + window_s; t += 0.05)
        if (std::abs(crossing.LateralAt(t) - user.lateral_m) < user.half_width_m + 0.6)
          return false;
      if (!path.closed()) break;
    }
  }
  return true;
}

uint16_t AddMover(BuildContext& ctx, MoverType type, int index_of_type, Rng& rng,
                  uint16_t next_id) {
  Scene& scene = *ctx.scene;
  const SynthOptions& opt = ctx.options;
  const double duration = ctx.duration_s;
  const double v = opt.speed_mps;
  Motion motion;
  std::vector<SceneInstance> made;
  auto make_instance = [&](ObjectClass cls, std::vector<BoxPrim> parts, double speed) {
    SceneInstance inst;
    inst.info.id = parts.empty() ? 0 : parts.front().instance_id;
    inst.info.object_class = cls;
    inst.info.moving = true;
    inst.info.speed_mps = speed;
    inst.info.size_m = PartsSize(parts);
    inst.parts = std::move(parts);
    made.push_back(std::move(inst));
  };
  constexpr int kAttempts = 60;
  switch (type) {
    case MoverType::kCarAhead: {
      motion.kind = Motion::Kind::kFollowPath;
      motion.path = scene.ego_path;
      const bool lead = opt.lead_gap_m > 0 && index_of_type == 0;
      for (int attempt = 0; attempt < kAttempts; ++attempt) {
        if (lead) {  // a queue: close ahead, a little slower or faster than the ego
          motion.speed_mps = v + rng.Uniform(0.0, 0.1);
          motion.s0_m = scene.ego_s0_m + opt.lead_gap_m + rng.Uniform(0, 2);
        } else {
          motion.speed_mps = v + rng.Uniform(0.4, 1.5);
          motion.s0_m = scene.ego_s0_m + 14.0 + 12.0 * index_of_type + rng.Uniform(0, 8 + attempt);
        }
        if (LaneIsFree(ctx, 0, motion)) break;
      }
      ctx.lane_users.push_back({0, 0.0, motion, lead ? 2.8 : 2.4, lead ? 1.05 : 0.95});
      make_instance(ObjectClass::kCar, lead ? MakeVan(rng, next_id) : MakeCar(rng, next_id),
                    motion.speed_mps);
      break;
    }
    case MoverType::kCarOncoming:
    case MoverType::kCyclistOncoming: {
      const bool car = type == MoverType::kCarOncoming;
      const int lane = car ? 1 : 2;
      const double offset = car ? -kLaneWidthM : -kLaneWidthM - 1.3;
      motion.kind = Motion::Kind::kFollowPath;
      motion.path = scene.ego_path.Offset(offset).Reversed();
      for (int attempt = 0; attempt < kAttempts; ++attempt) {
        motion.speed_mps = car ? rng.Uniform(6, 11) : rng.Uniform(3.5, 5.5);
        const double t_meet = rng.Uniform(0.15, 0.9) * duration;
        motion.s0_m = MeetingS(ctx, motion.path, t_meet, 0.0, offset) - motion.speed_mps * t_meet;
        if (LaneIsFree(ctx, lane, motion)) break;
      }
      ctx.lane_users.push_back({lane, offset, motion, car ? 2.4 : 0.9, car ? 0.95 : 0.35});
      if (car) {
        make_instance(ObjectClass::kCar, MakeCar(rng, next_id), motion.speed_mps);
      } else {
        make_instance(ObjectClass::kBicycle, MakeBicycle(rng, next_id), motion.speed_mps);
        std::vector<BoxPrim> rider;
        AddPerson(rng, static_cast<uint16_t>(next_id + 1), 1.0, 0.08, &rider, true);
        make_instance(ObjectClass::kPerson, std::move(rider), motion.speed_mps);
      }
      break;
    }
    case MoverType::kPersonWalking: {
      const int side = rng.Chance(0.5) ? 1 : -1;
      const double offset = side > 0 ? 7.5 - 0.5 * kLaneWidthM : -7.5 - 0.5 * kLaneWidthM;
      motion.kind = Motion::Kind::kFollowPath;
      motion.path = scene.ego_path.Offset(offset);
      if (rng.Chance(0.5)) motion.path = motion.path.Reversed();
      motion.speed_mps = rng.Uniform(1.1, 1.6);
      const double t_seen = rng.Uniform(0.1, 0.6) * duration;
      motion.s0_m = MeetingS(ctx, motion.path, t_seen, rng.Uniform(12, 35), offset) -
                    motion.speed_mps * t_seen;
      std::vector<BoxPrim> parts;
      AddPerson(rng, next_id, 0, 0, &parts, false);
      make_instance(ObjectClass::kPerson, std::move(parts), motion.speed_mps);
      break;
    }
    case MoverType::kPersonCrossing:
    case MoverType::kCyclistCrossing: {
      const bool person = type == MoverType::kPersonCrossing;
      motion.kind = Motion::Kind::kCrossing;
      // Sidewalk to sidewalk, relative to the ego lane centre.
      motion.lat_lo_m = -7.5 - 0.5 * kLaneWidthM;
      motion.lat_hi_m = 7.5 - 0.5 * kLaneWidthM;
      motion.speed_mps = person ? rng.Uniform(1.1, 1.6) : rng.Uniform(3.5, 5.0);
      const double span = motion.lat_hi_m - motion.lat_lo_m;
      for (int attempt = 0; attempt < 3 * kAttempts; ++attempt) {
        const double t_c = rng.Uniform(0.1, 0.75) * duration;
        const double s_c = StraightS(scene.ego_path, EgoS(ctx, t_c) + rng.Uniform(14, 30));
        const PathPoint base = scene.ego_path.At(s_c);
        motion.xz = base.xz;
        motion.heading_rad = base.heading_rad;
        const double lat_c = rng.Uniform(-6.0, 3.0);
        const bool to_right = rng.Chance(0.5);
        const double phase = to_right ? lat_c - motion.lat_lo_m : span + (motion.lat_hi_m - lat_c);
        motion.u0_m = phase - motion.speed_mps * t_c;
        if (CrossingIsClear(ctx, motion)) break;
      }
      ctx.crossings.push_back({motion.xz, motion.heading_rad});
      if (person) {
        std::vector<BoxPrim> parts;
        AddPerson(rng, next_id, 0, 0, &parts, false);
        make_instance(ObjectClass::kPerson, std::move(parts), motion.speed_mps);
      } else {
        make_instance(ObjectClass::kBicycle, MakeBicycle(rng, next_id), motion.speed_mps);
        std::vector<BoxPrim> rider;
        AddPerson(rng, static_cast<uint16_t>(next_id + 1), 1.0, 0.08, &rider, true);
        make_instance(ObjectClass::kPerson, std::move(rider), motion.speed_mps);
      }
      break;
    }
  }
  for (SceneInstance& inst : made) {
    inst.motion = motion;
    scene.instances.push_back(std::move(inst));
  }
  return static_cast<uint16_t>(next_id + made.size());
}

void AddParkedCars(BuildContext& ctx, Rng& rng, uint16_t* next_id) {
  Scene& scene = *ctx.scene;
  const SynthOptions& opt = ctx.options;
  std::vector<Eigen::Vector2d> lane_samples;
  const Path oncoming = scene.ego_path.Offset(-kLaneWidthM);
  const double lo = scene.ego_path.closed() ? 0.0 : scene.ego_s0_m - 10.0;
  const double hi =
      scene.ego_path.closed() ? scene.ego_path.Length() : EgoS(ctx, ctx.duration_s) + 60.0;
  for (double s = lo; s <= hi; s += 1.0) {
    lane_samples.push_back(scene.ego_path.At(s).xz);
    lane_samples.push_back(oncoming.At(s).xz);
  }
  std::vector<Rect2> placed;
  int attempts = 0;
  while (static_cast<int>(placed.size()) < opt.num_parked &&
         attempts++ < 400 * (opt.num_parked + 1)) {
    const size_t si =
        scene.ego_path.closed()
            ? static_cast<size_t>(rng.Uniform(0, static_cast<double>(scene.ground.streets.size())))
            : 0;
    const Street& street = scene.ground.streets[std::min(si, scene.ground.streets.size() - 1)];
    double s_lo = 0, s_hi = street.length_m;
    if (!scene.ego_path.closed()) {
      s_lo = kStreetBehindM + 5.0;
      s_hi = std::min(street.length_m, kStreetBehindM + opt.speed_mps * ctx.duration_s + 60.0);
    }
    const double s = rng.Uniform(s_lo, s_hi);
    const int side = rng.Chance(0.5) ? 1 : -1;
    const double lat =
        side * (kLaneWidthM + 0.5 * (kRoadHalfWidthM - kLaneWidthM) + rng.Uniform(-0.1, 0.1));
    const double heading = street.heading_rad + (side > 0 ? 0.0 : kPi) + rng.Uniform(-0.03, 0.03);
    const Eigen::Vector2d p = street.start_xz + s * street.Dir() + lat * street.Right();
    const Rect2 rect{p, heading, 1.0, 2.5};
    bool ok = true;
    for (const Rect2& other : placed)
      if (Overlaps(rect, other, -0.6)) ok = false;
    for (size_t k = 0; ok && k < scene.ground.streets.size(); ++k)
      if (&scene.ground.streets[k] != &street &&
          Overlaps(rect, StreetRect(scene.ground.streets[k], kRoadHalfWidthM + 3.0), 0.0))
        ok = false;
    for (const CrossingLine& c : ctx.crossings) {
      const Eigen::Vector2d d = p - c.xz;
      const Eigen::Vector2d fwd(std::sin(c.heading_rad), std::cos(c.heading_rad));
      if (std::abs(d.dot(fwd)) < 4.0 && d.norm() < 15.0) ok = false;
    }
    for (size_t k = 0; ok && k < lane_samples.size(); ++k)
      if (PointRectDistance(lane_samples[k], rect) < 1.3) ok = false;
    if (!ok) continue;
    placed.push_back(rect);
    SceneInstance inst;
    inst.info.id = (*next_id)++;
    inst.info.object_class = ObjectClass::kCar;
    inst.info.moving = false;
    inst.parts = MakeCar(rng, inst.info.id);
    inst.info.size_m = PartsSize(inst.parts);
    inst.motion.kind = Motion::Kind::kStatic;
    inst.motion.xz = p;
    inst.motion.heading_rad = heading;
    scene.instances.push_back(std::move(inst));
  }
}

}  // namespace

Scene BuildScene(const SynthOptions& opt) {
  Scene scene;
  const double duration = opt.frames / opt.rate_hz;
  const double travel = opt.speed_mps * duration;
  const double lane = 0.5 * kLaneWidthM;
  if (opt.route == RouteKind::kStraight) {
    const double length = kStreetBehindM + travel + 250.0;
    scene.ground.streets.push_back({{0.0, -kStreetBehindM}, 0.0, length});
    scene.ego_path = Path({lane, -kStreetBehindM}, 0.0);
    scene.ego_path.AddLine(length + 200.0);
    scene.ego_s0_m = kStreetBehindM;
  } else {
    // Rounded rectangle of streets, driven with left turns; the ego lane is on the outside.
    const double perimeter = std::max(travel / opt.laps, 1.0);
    const double lx = std::max(40.0, perimeter / 5.2), lz = 1.6 * lx;
    constexpr double kExt = 40.0;
    scene.ground.streets.push_back({{0.0, -kExt}, 0.0, lz + 2 * kExt});
    scene.ground.streets.push_back({{kExt, lz}, -0.5 * kPi, lx + 2 * kExt});
    scene.ground.streets.push_back({{-lx, lz + kExt}, kPi, lz + 2 * kExt});
    scene.ground.streets.push_back({{-lx - kExt, 0.0}, 0.5 * kPi, lx + 2 * kExt});
    const double x0 = lane, x1 = -lx - lane, z0 = -lane, z1 = lz + lane;
    const double r = kCornerRadiusM;
    Path path({x0, z0 + r}, 0.0);
    for (int i = 0; i < 2; ++i) {
      path.AddLine(z1 - z0 - 2 * r);
      path.AddArc(r, -0.5 * kPi);
      path.AddLine(x0 - x1 - 2 * r);
      path.AddArc(r, -0.5 * kPi);
    }
    path.Close();
    scene.ego_path = path;
    scene.ego_s0_m = 0.25 * (z1 - z0 - 2 * r);
  }
  Rng misc = MakeRng(opt.seed, kStreamMisc);
  scene.bounce_phase_seed = misc.U32();

  BuildContext ctx{opt, &scene, duration, {}, {}};
  uint16_t next_id = 1;
  // Parked cars take ids 1..P; movers follow. Movers are made first (parked cars avoid their
  // crossing lines) and renumbered afterwards.
  Rng movers = MakeRng(opt.seed, kStreamMovers);
  std::vector<int> count_of_type(6, 0);
  uint16_t mover_id = 30000;
  // The ego drives its lane too: crossing objects keep clear of it.
  Motion ego;
  ego.kind = Motion::Kind::kFollowPath;
  ego.path = scene.ego_path;
  ego.s0_m = scene.ego_s0_m;
  ego.speed_mps = opt.speed_mps;
  ctx.lane_users.push_back({0, 0.0, ego, 1.5, 1.3});
  // Vehicles first, then the objects that cross their lanes.
  for (int pass = 0; pass < 2; ++pass)
    for (int i = 0; i < opt.num_movers; ++i) {
      const MoverType type = kMoverCycle[i % 10];
      const bool crossing =
          type == MoverType::kPersonCrossing || type == MoverType::kCyclistCrossing;
      if (crossing != (pass == 1)) continue;
      mover_id = AddMover(ctx, type, count_of_type[static_cast<int>(type)]++, movers, mover_id);
    }
  std::vector<SceneInstance> mover_instances = std::move(scene.instances);
  scene.instances.clear();
  Rng parked = MakeRng(opt.seed, kStreamParked);
  AddParkedCars(ctx, parked, &next_id);
  for (SceneInstance& inst : mover_instances) {
    inst.info.id = next_id++;
    for (BoxPrim& part : inst.parts) part.instance_id = inst.info.id;
    scene.instances.push_back(std::move(inst));
  }

  Rng buildings = MakeRng(opt.seed, kStreamBuildings);
  AddBuildings(scene.ground.streets, buildings, &scene.static_boxes);
  AddSidewalks(scene.ground.streets, buildings, &scene.static_boxes);
  Rng poles = MakeRng(opt.seed, kStreamPoles);
  AddPoles(scene.ground.streets, poles, &scene.static_boxes);
  AddClutter(scene.ground.streets, poles, &scene.static_boxes);
  for (const CrossingLine& c : ctx.crossings) scene.ground.zebras.push_back({c.xz, c.heading_rad});
  return scene;
}

}  // namespace pcr::sim
