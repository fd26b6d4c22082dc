#pragma once
// Procedural texture building blocks for the synthetic world (internal to src/sim). All inputs
// are surface coordinates in metres; w, wx, wy are the pixel footprint (box-filter width) in the
// same units, so patterns are prefiltered instead of aliasing: stripes and cells are box-filtered
// exactly, noise octaves finer than the footprint fade out.
#include <algorithm>
#include <cmath>
#include <cstdint>

namespace pcr::sim::tex {

inline uint32_t Mix32(uint32_t h) {
  h ^= h >> 16;
  h *= 0x7feb352dU;
  h ^= h >> 15;
  h *= 0x846ca68bU;
  h ^= h >> 16;
  return h;
}

inline uint32_t Hash2(int32_t x, int32_t y, uint32_t seed) {
  return Mix32(static_cast<uint32_t>(x) * 0x8da6b343U + static_cast<uint32_t>(y) * 0xd8163841U +
               seed * 0xcb1ab31fU + 0x2545f491U);
}
inline uint32_t Hash1(uint32_t a, uint32_t seed) { return Mix32(a * 0x9e3779b1U + Mix32(seed)); }

// [0, 1) and [-1, 1).
inline double Unit(uint32_t h) { return static_cast<double>(h >> 8) * (1.0 / 16777216.0); }
inline double Signed(uint32_t h) { return 2.0 * Unit(h) - 1.0; }

inline double Saturate(double x) { return std::clamp(x, 0.0, 1.0); }
inline double Mix(double a, double b, double t) { return a + (b - a) * t; }

// Smooth value noise in [-1, 1] with unit lattice spacing.
inline double ValueNoise(double x, double y, uint32_t seed) {
  const double fx = std::floor(x), fy = std::floor(y);
  const int32_t ix = static_cast<int32_t>(fx), iy = static_cast<int32_t>(fy);
  const double tx = x - fx, ty = y - fy;
  const double sx = tx * tx * tx * (tx * (tx * 6 - 15) + 10);
  const double sy = ty * ty * ty * (ty * (ty * 6 - 15) + 10);
  const double v00 = Signed(Hash2(ix, iy, seed)), v10 = Signed(Hash2(ix + 1, iy, seed));
  const double v01 = Signed(Hash2(ix, iy + 1, seed)), v11 = Signed(Hash2(ix + 1, iy + 1, seed));
  return Mix(Mix(v00, v10, sx), Mix(v01, v11, sx), sy);
}

// Sum of value-noise octaves, the first with lattice spacing cell_m, each next one half as large
// and `gain` times as strong. An octave fades out as its spacing drops from 2w to w.
inline double Fbm(double x, double y, double w, uint32_t seed, double cell_m, int octaves,
                  double gain) {
  double sum = 0, amp = 1, cell = cell_m;
  for (int k = 0; k < octaves; ++k) {
    const double fade = w > 0 ? Saturate(cell / w - 1.0) : 1.0;
    if (fade <= 0) break;
    sum += amp * fade * ValueNoise(x / cell, y / cell, seed + 977U * static_cast<uint32_t>(k));
    amp *= gain;
    cell *= 0.5;
  }
  return sum;
}

// Splits the box [c - w/2, c + w/2] (w <= 1, unit cells) over at most two cells: first index and
// the weight of that first cell.
inline void SplitCells(double c, double w, int32_t* i0, double* w0) {
  const double lo = c - 0.5 * w;
  const double flo = std::floor(lo);
  *i0 = static_cast<int32_t>(flo);
  const double next = flo + 1.0;
  if (w <= 1e-12 || lo + w <= next) {
    *w0 = 1.0;
  } else {
    *w0 = (next - lo) / w;
  }
}

// Piecewise-constant random cells of cell_x by cell_y metres, values in [-1, 1], box-filtered
// exactly over the footprint; rows are shifted by half a cell when `stagger` (bricks, paving).
// Fades to 0 (the mean) as the footprint grows from half a cell to a cell.
inline double Cells(double x, double y, double wx, double wy, double cell_x, double cell_y,
                    uint32_t seed, bool stagger) {
  const double nx = wx / cell_x, ny = wy / cell_y;
  const double fade = Saturate(2.0 - 2.0 * std::max(nx, ny));
  if (fade <= 0) return 0;
  const double xs = x / cell_x, ys = y / cell_y;
  int32_t j0, i0;
  double wj0, wi0;
  SplitCells(ys, ny, &j0, &wj0);
  double sum = 0;
  for (int dj = 0; dj < 2; ++dj) {
    const double wj = dj == 0 ? wj0 : 1.0 - wj0;
    if (wj <= 0) continue;
    const int32_t j = j0 + dj;
    const double shift = stagger ? 0.5 * static_cast<double>(j & 1) : 0.0;
    SplitCells(xs + shift, nx, &i0, &wi0);
    double row = wi0 * Signed(Hash2(i0, j, seed));
    if (wi0 < 1.0) row += (1.0 - wi0) * Signed(Hash2(i0 + 1, j, seed));
    sum += wj * row;
  }
  return fade * sum;
}

// Box-filtered indicator of [lo, hi] (0 <= lo < hi <= period) repeated with `period`: the
// fraction of [x - w/2, x + w/2] covered; exact for any footprint.
inline double PeriodicPulse(double x, double w, double period, double lo, double hi) {
  const double duty = hi - lo;
  auto integral = [&](double v) {
    const double n = std::floor(v / period);
    return n * duty + std::clamp(v - n * period - lo, 0.0, duty);
  };
  if (w <= 1e-9) {
    const double r = x - std::floor(x / period) * period;
    return (r >= lo && r < hi) ? 1.0 : 0.0;
  }
  return (integral(x + 0.5 * w) - integral(x - 0.5 * w)) / w;
}

// Box-filtered indicator of [lo, hi].
inline double Pulse(double x, double w, double lo, double hi) {
  if (w <= 1e-9) return (x >= lo && x < hi) ? 1.0 : 0.0;
  const double a = std::max(lo, x - 0.5 * w), b = std::min(hi, x + 0.5 * w);
  return b > a ? (b - a) / w : 0.0;
}

// Index of the period holding x when the pattern's gaps are centred between repeats (so a
// per-repeat value changes only inside the gap between two pulses of [lo, hi]).
inline int32_t RepeatIndex(double x, double period, double lo, double hi) {
  return static_cast<int32_t>(std::floor((x - 0.5 * (lo + hi)) / period + 0.5));
}

}  // namespace pcr::sim::tex
