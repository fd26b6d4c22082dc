#include "sim/shading.h"

#include <algorithm>
#include <cmath>

#include "sim/texture.h"

namespace pcr::sim {

using tex::Cells;
using tex::Fbm;
using tex::Mix;
using tex::PeriodicPulse;
using tex::Pulse;
using tex::Saturate;
using tex::Unit;

namespace {

// Box-filtered rectangle [a0, a1] x [b0, b1].
double Rect(double a, double b, double wa, double wb, double a0, double a1, double b0, double b1) {
  return Pulse(a, wa, a0, a1) * Pulse(b, wb, b0, b1);
}

// Mortar/grout fraction of a staggered grid (bricks, paving): lines of `width` along both axes,
// the vertical ones shifted by half a cell on odd rows.
double StaggeredGrout(double a, double b, double wa, double wb, double cell_a, double cell_b,
                      double width) {
  const int32_t row = static_cast<int32_t>(std::floor(b / cell_b));
  const double shift = 0.5 * cell_a * static_cast<double>(row & 1);
  const double horizontal = 1.0 - PeriodicPulse(b, wb, cell_b, width, cell_b);
  const double vertical = (1.0 - PeriodicPulse(a + shift, wa, cell_a, width, cell_a)) *
                          Saturate(2.0 - 4.0 * wb / cell_b);
  return std::min(1.0, horizontal + vertical);
}

// Posters, vents, plates, stains, stones: at most one random rectangle per cell_a x cell_b cell
// (probability `density`), box-filtered exactly over the footprint (which may straddle cells);
// fades out as the footprint grows from half a cell to a cell. Returns the covered fraction and
// sets *tone to the covered part's mean tone (in [0.08, 0.93]).
double Decal(double a, double b, double wa, double wb, double cell_a, double cell_b, double density,
             uint32_t seed, double* tone) {
  const double fade = Saturate(2.0 - 2.0 * std::max(wa / cell_a, wb / cell_b));
  if (fade <= 0) return 0;
  // Fast path: the footprint lies in one cell.
  const double fa = a / cell_a, fb = b / cell_b;
  const double ca = std::floor(fa), cb = std::floor(fb);
  const double ha = 0.5 * wa / cell_a, hb = 0.5 * wb / cell_b;
  if (fa - ha >= ca && fa + ha < ca + 1 && fb - hb >= cb && fb + hb < cb + 1) {
    const int32_t ci = static_cast<int32_t>(ca), cj = static_cast<int32_t>(cb);
    const uint32_t h = tex::Hash2(ci, cj, seed);
    if (Unit(h) >= density) return 0;
    const uint32_t h2 = tex::Mix32(h), h3 = tex::Mix32(h2), h4 = tex::Mix32(h3);
    const double wid = cell_a * (0.25 + 0.6 * Unit(h2)), hgt = cell_b * (0.2 + 0.6 * Unit(h3));
    const double a0 = ci * cell_a + (cell_a - wid) * Unit(h4);
    const double b0 = cj * cell_b + (cell_b - hgt) * Unit(h4 << 10);
    const double m = Pulse(a, wa, a0, a0 + wid) * Pulse(b, wb, b0, b0 + hgt);
    if (m <= 0) return 0;
    *tone = 0.08 + 0.85 * Unit(h4 << 20);
    return fade * m;
  }
  const int32_t i0 = static_cast<int32_t>(std::floor((a - 0.5 * wa) / cell_a));
  const int32_t i1 = static_cast<int32_t>(std::floor((a + 0.5 * wa) / cell_a));
  const int32_t j0 = static_cast<int32_t>(std::floor((b - 0.5 * wb) / cell_b));
  const int32_t j1 = static_cast<int32_t>(std::floor((b + 0.5 * wb) / cell_b));
  double cover = 0, tone_sum = 0;
  for (int32_t cj = j0; cj <= j1; ++cj)
    for (int32_t ci = i0; ci <= i1; ++ci) {
      const uint32_t h = tex::Hash2(ci, cj, seed);
      if (Unit(h) >= density) continue;
      const uint32_t h2 = tex::Mix32(h), h3 = tex::Mix32(h2), h4 = tex::Mix32(h3);
      const double wid = cell_a * (0.25 + 0.6 * Unit(h2)), hgt = cell_b * (0.2 + 0.6 * Unit(h3));
      const double a0 = ci * cell_a + (cell_a - wid) * Unit(h4);
      const double b0 = cj * cell_b + (cell_b - hgt) * Unit(h4 << 10);
      const double m = Pulse(a, wa, a0, a0 + wid) * Pulse(b, wb, b0, b0 + hgt);
      if (m <= 0) continue;
      cover += m;
      tone_sum += m * (0.08 + 0.85 * Unit(h4 << 20));
    }
  if (cover <= 0) return 0;
  *tone = tone_sum / cover;
  return fade * std::min(1.0, cover);
}

// Coverage of dark sealed cracks: at most one straight crack per 3 m cell (probability 0.5).
double Crack(double x, double y, double w, uint32_t seed) {
  constexpr double kCell = 3.0, kHalfWidth = 0.02;
  const int32_t ci = static_cast<int32_t>(std::floor(x / kCell));
  const int32_t cj = static_cast<int32_t>(std::floor(y / kCell));
  const uint32_t h = tex::Hash2(ci, cj, seed);
  if ((h & 1U) == 0) return 0;
  const uint32_t h2 = tex::Mix32(h), h3 = tex::Mix32(h2);
  const Eigen::Vector2d p0((ci + 0.1 + 0.8 * Unit(h2)) * kCell,
                           (cj + 0.1 + 0.8 * Unit(h2 << 12)) * kCell);
  const Eigen::Vector2d p1((ci + 0.1 + 0.8 * Unit(h3)) * kCell,
                           (cj + 0.1 + 0.8 * Unit(h3 << 12)) * kCell);
  const Eigen::Vector2d seg = p1 - p0, q = Eigen::Vector2d(x, y) - p0;
  const double t = std::clamp(q.dot(seg) / std::max(seg.squaredNorm(), 1e-9), 0.0, 1.0);
  const double dist = (q - t * seg).norm();
  // Box-filtered line of width 2 kHalfWidth, fading once the footprint is 4x wider.
  const double fw = std::max(w, 1e-4);
  return Saturate((kHalfWidth + 0.5 * fw - dist) / fw) * std::min(1.0, 2 * kHalfWidth / fw) *
         Saturate(2.0 - w / (4 * kHalfWidth));
}

// Car licence plate: white with dark characters, width 0.52 m centred on a_mid.
double Plate(double value, double a, double b, double wa, double wb, double a_mid, double b0,
             uint32_t seed) {
  const double m = Rect(a, b, wa, wb, a_mid - 0.26, a_mid + 0.26, b0, b0 + 0.12);
  if (m <= 0) return value;
  const double chars = Rect(a, b, wa, wb, a_mid - 0.22, a_mid + 0.22, b0 + 0.025, b0 + 0.095) *
                       (0.5 + 0.5 * Cells(a, b, wa, wb, 0.055, 0.035, seed, false));
  return Mix(value, 0.9 - 0.75 * chars, m);
}

double ShadeFacade(const BoxPrim& box, int face, double a, double b, double wa, double wb) {
  const uint32_t seed = box.seed;
  const double w = std::max(wa, wb);
  if (face == 2 || face == 3)
    return 0.30 + 0.05 * Fbm(a, b, w, seed, 4.0, 4, 0.5) +
           0.04 * Cells(a, b, wa, wb, 2, 2, seed + 1, false);
  const double height = 2 * box.half_m.y();
  const double floor_h = box.param[0], ground_h = box.param[1], period = box.param[2];
  const double win_w = box.param[3], win_h = box.param[4], offset = box.param[5];
  const int style = static_cast<int>(box.param[6]);
  const int flags = static_cast<int>(box.param[7]);
  const double sill = 0.9;

  double wall = box.tone + 0.05 * Fbm(a, b, w, seed + 7, 14.0, 1, 0.5);
  if (style == 1) {  // bricks
    wall += 0.15 * Cells(a, b, wa, wb, 0.25, 0.075, seed, true) -
            0.28 * StaggeredGrout(a, b, wa, wb, 0.25, 0.075, 0.014) +
            0.03 * Fbm(a, b, w, seed + 2, 1.0, 2, 0.5);
  } else if (style == 2) {  // concrete panels
    const double ph = floor_h * 0.5;
    wall += 0.1 * Cells(a, b, wa, wb, 1.6, ph, seed, false) -
            0.15 * (PeriodicPulse(a, wa, 1.6, 0, 0.03) + PeriodicPulse(b, wb, ph, 0, 0.03)) +
            0.04 * Fbm(a, b, w, seed + 2, 0.8, 3, 0.6);
  } else {  // plaster
    wall += 0.06 * Fbm(a, b, w, seed + 2, 1.6, 3, 0.65) +
            0.07 * Cells(a, b, wa, wb, 0.45, 0.35, seed + 3, true);
  }
  // Stone plinth.
  const double plinth_h = box.param[8];
  const double plinth = Pulse(b, wb, 0, plinth_h);
  if (plinth > 0) {
    const double stone = box.param[9] + 0.14 * Cells(a, b, wa, wb, 0.6, 0.3, seed + 17, true) -
                         0.16 * StaggeredGrout(a, b, wa, wb, 0.6, 0.3, 0.015);
    wall = Mix(wall, stone, plinth);
  }
  double decal_tone = 0;
  const double decal = Decal(a, b, wa, wb, 1.7, 1.3, 0.45, seed + 21, &decal_tone);
  if (decal > 0) wall = Mix(wall, decal_tone, decal);

  double value = wall;
  if (b > ground_h - 0.5 * wb - 0.2) {
    const double rel_b = b - ground_h;
    const double upper = Pulse(b, wb, ground_h, height - 0.8);
    const double band = PeriodicPulse(rel_b, wb, floor_h, 0, 0.2) * upper;
    value = Mix(value, box.tone + 0.16, band);
    const double ax = a - offset;
    const double ma = PeriodicPulse(ax, wa, period, 0, win_w);
    const double mb = PeriodicPulse(rel_b, wb, floor_h, sill, sill + win_h);
    const double fa = PeriodicPulse(ax + 0.1, wa, period, 0, win_w + 0.2);
    const double fb = PeriodicPulse(rel_b + 0.1, wb, floor_h, sill, sill + win_h + 0.2);
    const double win_m = ma * mb * upper;
    const double frame_m = std::max(0.0, fa * fb * upper - win_m);
    const double frame_tone = (flags & 1) ? 0.8 : 0.22;
    value = Mix(value, frame_tone, frame_m);
    if (win_m > 0) {
      const int32_t ia = tex::RepeatIndex(ax, period, 0, win_w);
      const int32_t ib = tex::RepeatIndex(rel_b, floor_h, sill, sill + win_h);
      const uint32_t h = tex::Hash2(ia, ib, seed + 11);
      double glass = 0.12 + 0.22 * Unit(h) + 0.04 * Fbm(a, b, w, seed + 13, 0.7, 1, 0.5);
      const double local_b = rel_b - ib * floor_h - sill;
      const double local_a = ax - ia * period;
      if ((h & 3U) != 0) {  // blinds or curtains
        const double f = 0.15 + 0.7 * Unit(tex::Mix32(h));
        const double blind = Pulse(local_b, wb, win_h * (1 - f), win_h + 1);
        glass = Mix(glass, 0.5 + 0.35 * Unit(h >> 5), blind);
      }
      const double mullion = Pulse(local_a, wa, 0.5 * win_w - 0.04, 0.5 * win_w + 0.04) +
                             Pulse(local_b, wb, 0.62 * win_h - 0.03, 0.62 * win_h + 0.03);
      glass = Mix(glass, frame_tone, std::min(1.0, mullion));
      value = Mix(value, glass, win_m);
    }
  }
  if (b < ground_h + 0.5 * wb) {
    const double lower = Pulse(b, wb, 0, ground_h);
    const double shop_period = 2 * period;
    const double ax = a - offset;
    if (flags & 2) {  // shops: display windows and a sign band with lettering
      const double ma = PeriodicPulse(ax, wa, shop_period, 0, 0.72 * shop_period);
      const double glass_m = ma * Pulse(b, wb, 0.45, ground_h - 0.95) * lower;
      double display = 0.16 + 0.08 * Cells(a, b, wa, wb, 0.6, 0.45, seed + 3, false) +
                       0.05 * Fbm(a, b, w, seed + 4, 0.4, 2, 0.5);
      double item_tone = 0;
      const double item = Decal(a, b, wa, wb, 0.5, 0.6, 0.6, seed + 8, &item_tone);
      display = Mix(display, 0.15 + 0.35 * item_tone, item);
      value = Mix(value, display, glass_m);
      const double sign_m = ma * Pulse(b, wb, ground_h - 0.8, ground_h - 0.25);
      const double letters = 0.5 + 0.22 * Cells(a, b, wa, wb, 0.17, 0.22, seed + 5, false);
      value = Mix(value, letters, sign_m);
    } else {  // doors, barred windows and posters
      const double win = PeriodicPulse(ax, wa, period, 0, win_w) * Pulse(b, wb, 1.2, 2.6) * lower;
      const double bars = PeriodicPulse(ax, wa, 0.18, 0, 0.035);
      value = Mix(value, Mix(box.param[10], 0.55, bars), win);
      const double door = PeriodicPulse(ax, wa, 3 * period, 0.3, 1.4) * Pulse(b, wb, 0, 2.2);
      value = Mix(value, 0.16 + 0.05 * Cells(a, b, wa, wb, 0.55, 0.7, seed + 6, false), door);
      double poster_tone = 0;
      const double poster =
          Decal(a, b, wa, wb, 1.1, 1.6, 0.35, seed + 23, &poster_tone) * Pulse(b, wb, 0.3, 2.6);
      value = Mix(value, 0.2 + 0.6 * poster_tone, poster);
    }
  }
  return value;
}

double ShadeSidewalk(const BoxPrim& box, int face, double a, double b, double wa, double wb) {
  const uint32_t seed = box.seed;
  const double w = std::max(wa, wb);
  if (face == 2) {
    constexpr double kTile = 0.5;
    double v = box.tone + 0.15 * Cells(a, b, wa, wb, kTile, kTile, seed, true) +
               0.04 * Fbm(a, b, w, seed + 1, 1.0, 3, 0.55);
    v -= 0.2 * StaggeredGrout(a, b, wa, wb, kTile, kTile, 0.015);
    double tone = 0;
    const double stain = Decal(a, b, wa, wb, 1.3, 1.3, 0.3, seed + 2, &tone);
    return Mix(v, 0.2 + 0.6 * tone, stain);
  }
  // Kerb stones.
  return 0.62 + 0.06 * Cells(a, b, wa, wb, 1.0, 1.0, seed + 2, false) +
         0.04 * Fbm(a, b, w, seed + 3, 0.5, 4, 0.5) - 0.2 * PeriodicPulse(a, wa, 1.0, 0, 0.012);
}

double ShadeCarBody(const BoxPrim& box, int face, double a, double b, double wa, double wb) {
  const uint32_t seed = box.seed;
  const double w = std::max(wa, wb);
  // Paint mirrors its surroundings (mottled reflections) and collects dirt and stickers: real
  // cars give a detector corners, not flat boxes.
  double v = box.tone + 0.025 * Fbm(a, b, w, seed, 1.0, 4, 0.5) +
             0.16 * (Fbm(a, b, w, seed + 31, 0.3, 3, 0.5) - 0.5);
  double dirt_tone = 0;
  const double dirt = Decal(a, b, wa, wb, 0.35, 0.25, 0.4, seed + 33, &dirt_tone);
  v = Mix(v, 0.12 + 0.76 * dirt_tone, 0.8 * dirt);
  const double len = 2 * box.half_m.z(), wid = 2 * box.half_m.x(), hgt = 2 * box.half_m.y();
  if (face == 0 || face == 1) {
    const double seams = Pulse(a, wa, 0.36 * len, 0.36 * len + 0.015) +
                         Pulse(a, wa, 0.62 * len, 0.62 * len + 0.015) +
                         Pulse(b, wb, 0.55 * hgt, 0.55 * hgt + 0.03);
    v = Mix(v, 0.5 * box.tone, std::min(1.0, seams));
    const double handles =
        Rect(a, b, wa, wb, 0.40 * len, 0.40 * len + 0.2, 0.7 * hgt, 0.7 * hgt + 0.05) +
        Rect(a, b, wa, wb, 0.66 * len, 0.66 * len + 0.2, 0.7 * hgt, 0.7 * hgt + 0.05);
    v = Mix(v, 0.1, handles);
    v = Mix(v, 0.08, Pulse(b, wb, 0, 0.08));  // sill
  } else if (face == 4 || face == 5) {
    const bool front = face == 5;
    // On the +z face a runs along +x; lights sit near both sides.
    const double lights = Rect(a, b, wa, wb, 0.08, 0.45, 0.55 * hgt, 0.85 * hgt) +
                          Rect(a, b, wa, wb, wid - 0.45, wid - 0.08, 0.55 * hgt, 0.85 * hgt);
    v = Mix(v, front ? 0.95 : 0.32, lights);
    if (front) {
      const double grille = Rect(a, b, wa, wb, 0.55, wid - 0.55, 0.3 * hgt, 0.75 * hgt);
      v = Mix(v, 0.1 + 0.25 * PeriodicPulse(b, wb, 0.05, 0, 0.02), grille);
    }
    v = Plate(v, a, b, wa, wb, 0.5 * wid, 0.1 * hgt, seed + 9);
    v = Mix(v, 0.1, Pulse(b, wb, 0, 0.1));  // bumper
  }
  return v;
}

double ShadeCabin(const BoxPrim& box, int face, double a, double b, double wa, double wb) {
  const uint32_t seed = box.seed;
  const double w = std::max(wa, wb);
  if (face == 2 || face == 3) return box.tone + 0.02 * Fbm(a, b, w, seed, 1.0, 3, 0.5);
  const double len = (face == 0 || face == 1) ? 2 * box.half_m.z() : 2 * box.half_m.x();
  const double hgt = 2 * box.half_m.y();
  const double glass_m = Rect(a, b, wa, wb, 0.1, len - 0.1, 0.06, hgt - 0.07);
  const double pillar =
      (face == 0 || face == 1) ? Pulse(a, wa, 0.5 * len - 0.05, 0.5 * len + 0.05) : 0.0;
  const double glass = 0.08 + 0.3 * Fbm(a, b, w, seed + 1, 0.35, 3, 0.5) +
                       0.1 * Pulse(b, wb, hgt - 0.2, hgt - 0.12);  // reflection band
  double v = box.tone + 0.02 * Fbm(a, b, w, seed, 1.0, 3, 0.5);
  return Mix(v, glass, glass_m * (1.0 - pillar));
}

double ShadeWheel(const BoxPrim& box, int face, double a, double b, double wa, double wb) {
  double v = 0.07 + 0.02 * Cells(a, b, wa, wb, 0.05, 0.05, box.seed, false);
  if (face == 0 || face == 1) {
    const double size = 2 * box.half_m.z(), lo = 0.22 * size, hi = 0.78 * size;
    const double rim = Rect(a, b, wa, wb, lo, hi, lo, hi);
    const double spokes = 0.45 + 0.2 * Cells(a, b, wa, wb, 0.07, 0.07, box.seed + 1, false);
    v = Mix(v, spokes, rim);
    v = Mix(v, 0.15, Rect(a, b, wa, wb, 0.45 * size, 0.55 * size, 0.45 * size, 0.55 * size));
  }
  return v;
}

double ShadePerson(const BoxPrim& box, int face, double a, double b, double wa, double wb) {
  const uint32_t seed = box.seed;
  const double w = std::max(wa, wb);
  const double wid = (face == 0 || face == 1) ? 2 * box.half_m.z() : 2 * box.half_m.x();
  const double hgt = 2 * box.half_m.y();
  double v = box.tone + 0.04 * Fbm(a, b, w, seed, 0.3, 4, 0.5);
  switch (box.material) {
    case Material::kLegs:
      if (face == 4 || face == 5)
        v = Mix(v, 0.06,
                Rect(a, b, wa, wb, 0.5 * wid - 0.025, 0.5 * wid + 0.025, 0.08, hgt - 0.15));
      v = Mix(v, 0.08, Pulse(b, wb, 0, 0.08));  // shoes
      break;
    case Material::kTorso:
      v = Mix(v, box.tone * 0.6, Pulse(a, wa, 0.09, 0.12) + Pulse(a, wa, wid - 0.12, wid - 0.09));
      v = Mix(v, 0.6, Pulse(b, wb, 0.05 * hgt, 0.1 * hgt));  // belt / hem
      break;
    default:  // head: skin below, hair above
      if (face == 2) return 0.12;
      v = Mix(v, 0.12 + 0.1 * box.param[0], Pulse(b, wb, 0.62 * hgt, hgt + 1));
      if (face == 5)
        v = Mix(v, 0.15, Rect(a, b, wa, wb, 0.3 * wid, 0.7 * wid, 0.5 * hgt, 0.56 * hgt));
      break;
  }
  return v;
}

double ShadeBike(const BoxPrim& box, int face, double a, double b, double wa, double wb) {
  if (box.material == Material::kBikeFrame)
    return box.tone + 0.04 * Fbm(a, b, std::max(wa, wb), box.seed, 0.2, 3, 0.5);
  double v = 0.08;
  if (face == 0 || face == 1) {
    const double size = 2 * box.half_m.z(), lo = 0.08 * size, hi = 0.92 * size;
    v = Mix(v, 0.35 + 0.25 * Cells(a, b, wa, wb, 0.06, 0.06, box.seed, false),
            Rect(a, b, wa, wb, lo, hi, lo, hi));
    v = Mix(v, 0.75, Rect(a, b, wa, wb, 0.45 * size, 0.55 * size, 0.45 * size, 0.55 * size));
  }
  return v;
}

double ShadePole(const BoxPrim& box, int face, double a, double b, double wa, double wb) {
  const double w = std::max(wa, wb);
  (void)face;
  double v = box.tone + 0.05 * Fbm(a, b, w, box.seed, 0.6, 4, 0.5);
  v = Mix(v, 0.2, Pulse(b, wb, 0, 0.35));
  v = Mix(v, box.tone + 0.2, PeriodicPulse(b, wb, 1.7, 0, 0.1) * Pulse(b, wb, 2.0, 4.5));
  return v;
}

double ShadeSign(const BoxPrim& box, int face, double a, double b, double wa, double wb) {
  if (face != 4 && face != 5) return 0.45;
  const double size = 2 * box.half_m.x(), hgt = 2 * box.half_m.y();
  if (face == 4) return 0.5 + 0.05 * Fbm(a, b, std::max(wa, wb), box.seed, 0.3, 3, 0.5);
  double v = 0.88;
  const double inner = Rect(a, b, wa, wb, 0.07, size - 0.07, 0.07, hgt - 0.07);
  const double border = Rect(a, b, wa, wb, 0.015, size - 0.015, 0.015, hgt - 0.015) - inner;
  v = Mix(v, box.tone, std::max(0.0, border));
  const double symbol = Rect(a, b, wa, wb, 0.17, size - 0.17, 0.17, hgt - 0.17) *
                        (0.5 + 0.5 * Cells(a, b, wa, wb, 0.09, 0.09, box.seed, false));
  return Mix(v, 0.12, symbol);
}

double ShadeClutter(const BoxPrim& box, int face, double a, double b, double wa, double wb) {
  const double w = std::max(wa, wb);
  double v = box.tone + 0.05 * Fbm(a, b, w, box.seed, 0.4, 3, 0.5);
  if (face == 2) return v + 0.1;
  const double hgt = 2 * box.half_m.y();
  v = Mix(v, 0.9 - 0.7 * box.tone, Pulse(b, wb, 0.75 * hgt, 0.82 * hgt));  // band
  double tone = 0;
  const double sticker = Decal(a, b, wa, wb, 0.3, 0.35, 0.5, box.seed + 1, &tone);
  return Mix(v, tone, sticker);
}

double ShadeBalcony(const BoxPrim& box, int face, double a, double b, double wa, double wb) {
  if (face == 2 || face == 3) return box.tone * 0.8;
  const double hgt = 2 * box.half_m.y();
  const double slab = Pulse(b, wb, 0, 0.18), rail = Pulse(b, wb, hgt - 0.07, hgt + 1);
  const double bars = PeriodicPulse(a, wa, 0.13, 0, 0.035);
  // Between the bars the (shadowed) balcony floor and wall show through.
  double v = Mix(0.16 + 0.05 * Cells(a, b, wa, wb, 0.4, 0.3, box.seed, false), box.tone, bars);
  v = Mix(v, 0.85, slab);
  return Mix(v, box.tone * 0.7, rail);
}

double ShadeHedge(const BoxPrim& box, double a, double b, double wa, double wb) {
  const double leaves = Cells(a, b, wa, wb, 0.07, 0.06, box.seed, true);
  const double clumps = Cells(a, b, wa, wb, 0.23, 0.19, box.seed + 1, false);
  return box.tone + 0.14 * leaves + 0.1 * clumps +
         0.05 * Fbm(a, b, std::max(wa, wb), box.seed + 2, 1.0, 2, 0.5);
}

}  // namespace

double ShadeBox(const BoxPrim& box, int face, double a, double b, double wa, double wb) {
  double v;
  switch (box.material) {
    case Material::kFacade:
      v = ShadeFacade(box, face, a, b, wa, wb);
      break;
    case Material::kSidewalk:
      v = ShadeSidewalk(box, face, a, b, wa, wb);
      break;
    case Material::kPole:
      v = ShadePole(box, face, a, b, wa, wb);
      break;
    case Material::kSign:
      v = ShadeSign(box, face, a, b, wa, wb);
      break;
    case Material::kCarBody:
      v = ShadeCarBody(box, face, a, b, wa, wb);
      break;
    case Material::kCarCabin:
      v = ShadeCabin(box, face, a, b, wa, wb);
      break;
    case Material::kWheel:
      v = ShadeWheel(box, face, a, b, wa, wb);
      break;
    case Material::kLegs:
    case Material::kTorso:
    case Material::kHead:
      v = ShadePerson(box, face, a, b, wa, wb);
      break;
    case Material::kClutter:
      v = ShadeClutter(box, face, a, b, wa, wb);
      break;
    case Material::kHedge:
      v = ShadeHedge(box, a, b, wa, wb);
      break;
    case Material::kBalcony:
      v = ShadeBalcony(box, face, a, b, wa, wb);
      break;
    default:
      v = ShadeBike(box, face, a, b, wa, wb);
      break;
  }
  return Saturate(v);
}

double ShadeGround(const Ground& ground, double x, double z, double dx_u, double dz_u, double dx_v,
                   double dz_v) {
  const double wx = std::abs(dx_u) + std::abs(dx_v), wz = std::abs(dz_u) + std::abs(dz_v);
  const double w = std::max(wx, wz);
  int inside = 0, street_index = 0;
  double s = 0, l = 0, ws = 0, wl = 0;
  const std::vector<Street>& streets = ground.streets;
  for (int si = 0; si < static_cast<int>(streets.size()); ++si) {
    const Street& street = streets[static_cast<size_t>(si)];
    const Eigen::Vector2d sl = street.Local({x, z});
    if (sl.x() < 0 || sl.x() > street.length_m || std::abs(sl.y()) > kRoadHalfWidthM) continue;
    if (++inside > 1) break;
    street_index = si;
    const Eigen::Vector2d dir = street.Dir(), right = street.Right();
    s = sl.x();
    l = sl.y();
    ws = std::abs(dx_u * dir.x() + dz_u * dir.y()) + std::abs(dx_v * dir.x() + dz_v * dir.y());
    wl = std::abs(dx_u * right.x() + dz_u * right.y()) +
         std::abs(dx_v * right.x() + dz_v * right.y());
  }
  if (inside == 0)
    return Saturate(0.34 + 0.08 * Fbm(x, z, w, 29, 2.0, 4, 0.55) +
                    0.08 * Cells(x, z, wx, wz, 0.3, 0.3, 43, false));
  double v = 0.29 + 0.04 * Fbm(x, z, w, 17, 8.0, 2, 0.5) + 0.05 * Fbm(x, z, w, 19, 0.4, 3, 0.6) +
             0.04 * Cells(x, z, wx, wz, 0.05, 0.05, 41, false);
  // Stones, tar spots, stains and small repairs, elongated along the street so that they stay
  // visible (and corner-like) at the grazing angles the camera sees the road under.
  const uint32_t street_seed = static_cast<uint32_t>(street_index) * 101U;
  double spot_tone = 0;
  double spot = Decal(l, s, wl, ws, 0.3, 0.8, 0.35, 37 + street_seed, &spot_tone);
  v = Mix(v, 0.14 + 0.42 * spot_tone, spot);
  spot = Decal(l, s, wl, ws, 1.0, 2.5, 0.3, 39 + street_seed, &spot_tone);
  v = Mix(v, 0.15 + 0.35 * spot_tone, spot);
  double patch_tone = 0;
  const double patch = Decal(x, z, wx, wz, 5.0, 4.0, 0.45, 23, &patch_tone);
  v = Mix(v, v - 0.1 + 0.2 * patch_tone, patch);
  v = Mix(v, 0.12, Crack(x, z, w, 53));
  if (inside == 1) {
    // Stencilled words in the lanes.
    const double word_cell = 37.0;
    const int32_t wk = static_cast<int32_t>(std::floor(s / word_cell));
    const uint32_t wh = tex::Hash2(wk, street_index, 67);
    const double ws0 = wk * word_cell + 3 + (word_cell - 8) * Unit(wh);
    const double wl0 = ((wh & 1U) ? 1.0 : -1.0) * 0.5 * kLaneWidthM;
    const double word = Rect(l, s, wl, ws, wl0 - 0.8, wl0 + 0.8, ws0, ws0 + 2.4);
    if (word > 0) {
      const double strokes = Saturate(0.5 + 2.5 * Cells(l, s, wl, ws, 0.2, 0.45, wh, false));
      v = Mix(v, 0.78, 0.9 * word * strokes);
    }
    // Manhole covers in the lanes and drains along the kerbs.
    const double cell_s = 17.0;
    const int32_t k = static_cast<int32_t>(std::floor(s / cell_s));
    const uint32_t h = tex::Hash2(k, street_index, 61);
    const double s0 = k * cell_s + 2 + (cell_s - 4) * Unit(h);
    const double l0 = ((h & 1U) ? 1.0 : -1.0) * (0.5 * kLaneWidthM + 0.6 * Unit(h >> 3) - 0.3);
    const double cover = Rect(s, l, ws, wl, s0 - 0.35, s0 + 0.35, l0 - 0.35, l0 + 0.35);
    if (cover > 0) v = Mix(v, 0.2 + 0.18 * Cells(s, l, ws, wl, 0.09, 0.09, h, false), cover);
    const double drain_s = (k + 0.5) * cell_s;
    const double drain_l = ((h & 2U) ? 1.0 : -1.0) * (kRoadHalfWidthM - 0.25);
    const double drain =
        Rect(s, l, ws, wl, drain_s - 0.25, drain_s + 0.25, drain_l - 0.2, drain_l + 0.2);
    if (drain > 0) v = Mix(v, 0.08 + 0.35 * PeriodicPulse(s, ws, 0.06, 0, 0.025), drain);
    const double dash = Pulse(l, wl, -0.07, 0.07) * PeriodicPulse(s, ws, 9.0, 0, 3.0);
    const double edges = Pulse(l, wl, kLaneWidthM - 0.06, kLaneWidthM + 0.06) +
                         Pulse(l, wl, -kLaneWidthM - 0.06, -kLaneWidthM + 0.06);
    const double bays = (Pulse(l, wl, kLaneWidthM + 0.06, kRoadHalfWidthM) +
                         Pulse(l, wl, -kRoadHalfWidthM, -kLaneWidthM - 0.06)) *
                        PeriodicPulse(s, ws, 5.5, 0, 0.1);
    const double m = std::min(1.0, dash + edges + bays);
    if (m > 0) v = Mix(v, 0.78 + 0.06 * Fbm(x, z, w, 31, 0.6, 3, 0.5), 0.92 * m);
  }
  for (const Zebra& zebra : ground.zebras) {
    const Eigen::Vector2d d = Eigen::Vector2d(x, z) - zebra.center_xz;
    if (d.squaredNorm() > 64.0) continue;
    const Eigen::Vector2d dir(std::sin(zebra.heading_rad), std::cos(zebra.heading_rad));
    const Eigen::Vector2d right(dir.y(), -dir.x());
    const double zs = d.dot(dir), zl = d.dot(right);
    const double zws =
        std::abs(dx_u * dir.x() + dz_u * dir.y()) + std::abs(dx_v * dir.x() + dz_v * dir.y());
    const double zwl = std::abs(dx_u * right.x() + dz_u * right.y()) +
                       std::abs(dx_v * right.x() + dz_v * right.y());
    const double stripes = Pulse(zs, zws, -1.5, 1.5) * Pulse(zl, zwl, -5.25, 5.25) *
                           PeriodicPulse(zl + 0.25, zwl, 1.0, 0, 0.5);
    v = Mix(v, 0.8 + 0.05 * Fbm(x, z, w, 59, 0.5, 3, 0.5), 0.92 * stripes);
  }
  return Saturate(v);
}

double SkyRadiance(double sin_elevation) { return 0.80 + 0.1 * Saturate(3.0 * sin_elevation); }

double Haze(double radiance, double distance_m) {
  constexpr double kHazeRadiance = 0.8, kHalfContrastM = 250.0;
  const double keep = std::exp2(-distance_m / kHalfContrastM);
  return kHazeRadiance + (radiance - kHazeRadiance) * keep;
}

double LightFactor(double nx, double ny, double nz) {
  // Overcast light from straight above (map y points down): every facade orientation gets the
  // same light, so neither side of a street is favoured; exposure 1.3.
  (void)nx;
  (void)nz;
  return 1.3 * (0.62 + 0.38 * std::max(0.0, -ny));
}

}  // namespace pcr::sim
