#pragma once
// Per-point math of the pyramidal Lucas-Kanade tracker (Bouguet's algorithm, with the semantics
// of cv::calcOpticalFlowPyrLK on pyramids from cv::buildOpticalFlowPyramid withDerivatives),
// shared by the CUDA engine's kernel (lk_flow_cuda.cu: one warp per point) and its CPU twin
// (lk_flow.cpp: one thread per point), so that both produce the same numbers from the same code.
//
// Fixed point as OpenCV's tracker: bilinear weights with kLkWeightBits fraction bits, window
// intensities in 1/32 grey levels (int16), window derivatives in Scharr units (int16). The sums
// over a window are exact (64-bit integers, where OpenCV adds in float), so that they do not
// depend on the order in which the lanes of a warp add them up. Float arithmetic that a device
// compiler would fuse into an FMA goes through LkMul, so host and device round alike.
//
// Views hold device or host pointers, never own them, and are copied into kernels by value.
// Coordinates are pixels of a level: x right, y down, pixel (x, y) at its centre.
#include <cmath>
#include <cstdint>

#include "gpu/tensor_math.h"  // PCR_HD

namespace pcr::gpu {

inline constexpr int kLkMaxLevels = 12;   // pyramid levels 0..kLkMaxLevels-1
inline constexpr int kLkWeightBits = 14;  // fraction bits of the bilinear weights
inline constexpr int kLkWindowShift = 9;  // weights x 8-bit pixel -> 1/32 grey level (14 - 5)
inline constexpr float kLkSumScale = 1.0f / (1 << 20);  // window sums -> OpenCV's float units

// One 8-bit image level. Readable: rows [-border, rows + border) and columns
// [-border, cols + border) around `origin`, which is pixel (0, 0).
struct LkImageView {
  const uint8_t* origin = nullptr;
  int step = 0;  // bytes from one row to the next
  int cols = 0, rows = 0;
  int border = 0;
};

// One derivative level: int16 pairs (d/dx, d/dy) per pixel, Scharr filter units. Readable
// as LkImageView's.
struct LkDerivView {
  const int16_t* origin = nullptr;
  int step = 0;  // int16 elements from one row to the next
  int cols = 0, rows = 0;
  int border = 0;
};

// What one level of a pass reads: the `from` image and its derivatives (the window around the
// start point) and the `to` image (the window around the moving estimate), all of one size.
struct LkLevelViews {
  LkImageView from_image;
  LkDerivView from_deriv;
  LkImageView to_image;
};

struct LkPyramidViews {
  LkLevelViews level[kLkMaxLevels];
  int max_level = 0;  // levels 0..max_level are used, coarsest first
};

// A pass's settings, after OpenCV's clamping (see lk_flow.h: LkSettingsFor).
struct LkSettings {
  int window = 21;                // odd
  int max_iterations = 20;        // per level, 0..100
  double epsilon_sq = 1e-4;       // stop when |step|^2 <= this (px^2 of the level)
  float min_eigen = 1e-4f;        // lost below this minimum eigenvalue / window area
  bool use_initial_flow = false;  // start from the guess instead of the start point
};

struct LkPointResult {
  float x = 0.0f, y = 0.0f;  // position in `to` (level 0 pixels)
  float error = 0.0f;        // mean |to window - from window|, grey levels; 0 when lost
  uint8_t status = 0;        // 1: found
};

// ---- Rounding as OpenCV's tracker rounds, on the host and on a device alike ----

// a * b rounded once (a device compiler must not fuse it into a following add).
PCR_HD inline float LkMul(float a, float b) {
#if defined(__CUDA_ARCH__)
  return __fmul_rn(a, b);
#else
  return a * b;
#endif
}
PCR_HD inline double LkMul(double a, double b) {
#if defined(__CUDA_ARCH__)
  return __dmul_rn(a, b);
#else
  return a * b;
#endif
}

// Nearest integer, ties to even (cvRound).
PCR_HD inline int LkRound(float v) {
#if defined(__CUDA_ARCH__)
  return __float2int_rn(v);
#else
  return static_cast<int>(std::lrint(v));
#endif
}

// The integer pixel at or left of / above (x, y) (cvFloor); false when a coordinate is not a
// finite number of moderate size (such a point is outside every image).
PCR_HD inline bool LkFloor(float x, float y, int* ix, int* iy) {
  constexpr float kFar = 1e8f;
  if (!(x > -kFar && x < kFar && y > -kFar && y < kFar)) return false;  // NaN fails too
  *ix = static_cast<int>(floorf(x));
  *iy = static_cast<int>(floorf(y));
  return true;
}

// Whether a window of `window` pixels whose top-left pixel is (ix, iy) may be tracked on a level
// of cols x rows: OpenCV's test (the window overlaps the image or touches it), and the window
// with its bilinear neighbours (one more column and row) lies in the stored border. With a
// border of at least `window` pixels, as the pyramids have, the second part always holds when
// the first does.
PCR_HD inline bool LkWindowFits(int ix, int iy, int window, int cols, int rows, int border) {
  return ix >= -window && ix < cols && iy >= -window && iy < rows && ix >= -border &&
         iy >= -border && ix + window < cols + border && iy + window < rows + border;
}

// Bilinear weights of the four pixels around a point at fraction (a, b) of a pixel right and
// below its top-left pixel, kLkWeightBits fixed point, summing to 1 << kLkWeightBits.
struct LkWeights {
  int w00 = 0, w01 = 0, w10 = 0, w11 = 0;  // top-left, top-right, bottom-left, bottom-right
};

PCR_HD inline LkWeights LkBilinearWeights(float a, float b) {
  constexpr float kOne = static_cast<float>(1 << kLkWeightBits);
  LkWeights w;
  w.w00 = LkRound(LkMul(LkMul(1.0f - a, 1.0f - b), kOne));
  w.w01 = LkRound(LkMul(LkMul(a, 1.0f - b), kOne));
  w.w10 = LkRound(LkMul(LkMul(1.0f - a, b), kOne));
  w.w11 = (1 << kLkWeightBits) - w.w00 - w.w01 - w.w10;
  return w;
}

// The image interpolated at `p` (a pointer to the top-left pixel), in 1/32 grey levels.
PCR_HD inline int LkSampleImage(const uint8_t* p, int step, const LkWeights& w) {
  const int sum = p[0] * w.w00 + p[1] * w.w01 + p[step] * w.w10 + p[step + 1] * w.w11;
  return (sum + (1 << (kLkWindowShift - 1))) >> kLkWindowShift;
}

// The derivatives interpolated at `p` (a pointer to the top-left pixel's d/dx), Scharr units.
PCR_HD inline void LkSampleDeriv(const int16_t* p, int step, const LkWeights& w, int* dx, int* dy) {
  constexpr int kHalf = 1 << (kLkWeightBits - 1);
  *dx = (p[0] * w.w00 + p[2] * w.w01 + p[step] * w.w10 + p[step + 2] * w.w11 + kHalf) >>
        kLkWeightBits;
  *dy = (p[1] * w.w00 + p[3] * w.w01 + p[step + 1] * w.w10 + p[step + 3] * w.w11 + kHalf) >>
        kLkWeightBits;
}

// ---- Lanes: who computes which pixels of a window ----
//
// LkTrackPoint is written for a group of lanes that track one point together: each lane visits
// the window pixels k = first, first + stride, ... (k = y * window + x) and Sum() adds a value
// over the lanes and hands every lane the total. Every lane computes the same scalar decisions
// from the same totals, so the group stays in step. A lane reads back only the window-buffer
// entries it wrote itself. Buffers: image_window holds window^2 int16, deriv_window 2 window^2.
//
// LkSerialLanes is the CPU twin's group of one; the CUDA kernel's warp is in lk_flow_cuda.cu.
struct LkSerialLanes {
  int16_t* image_window = nullptr;
  int16_t* deriv_window = nullptr;
  int first = 0;
  int stride = 1;
  PCR_HD int64_t Sum(int64_t v) const { return v; }
};

// Calls f(x, y, k) for the window pixels of a lane. A group of one walks rows (a loop the host
// compiler can unroll); a wider group steps through the pixels without divisions.
template <class F>
PCR_HD inline void LkForEachPixel(int window, int first, int stride, F&& f) {
  if (stride == 1) {
    for (int y = 0, k = 0; y < window; ++y) {
      for (int x = 0; x < window; ++x, ++k) f(x, y, k);
    }
    return;
  }
  const int area = window * window;
  int y = first / window, x = first - y * window;
  const int step_y = stride / window, step_x = stride - step_y * window;
  for (int k = first; k < area; k += stride) {
    f(x, y, k);
    x += step_x;
    y += step_y;
    if (x >= window) {
      x -= window;
      ++y;
    }
  }
}

// Tracks one point from `from` into `to` over levels max_level..0. (from_x, from_y): the point in
// `from`; (guess_x, guess_y): its starting position in `to` when settings.use_initial_flow (else
// unused); both level-0 pixels. As cv::calcOpticalFlowPyrLK: on each level the spatial gradient
// matrix of the `from` window is inverted once and the position iterates until the step is
// within epsilon, max_iterations is reached or the step reverses (then half a step back); a
// level whose window leaves the image or whose matrix is near singular keeps the position it
// started with, and on level 0 either loses the point. The error is that of the final position,
// on level 0. Views must satisfy LkWindowFits's border for every window they are asked for,
// which the function itself checks before reading.
template <class Lanes>
PCR_HD inline LkPointResult LkTrackPoint(const Lanes& lanes, const LkPyramidViews& pyramid,
                                         const LkSettings& s, float from_x, float from_y,
                                         float guess_x, float guess_y) {
  const int window = s.window;
  const int area = window * window;
  const float half = (window - 1) * 0.5f;
  int16_t* const image_window = lanes.image_window;
  int16_t* const deriv_window = lanes.deriv_window;

  LkPointResult result;
  result.status = 1;
  float next_x = 0.0f, next_y = 0.0f;  // the estimate in `to` on the current level
  for (int level = pyramid.max_level; level >= 0; --level) {
    const LkLevelViews& v = pyramid.level[level];
    const float scale = 1.0f / static_cast<float>(1 << level);
    if (level == pyramid.max_level) {
      next_x = (s.use_initial_flow ? guess_x : from_x) * scale;
      next_y = (s.use_initial_flow ? guess_y : from_y) * scale;
    } else {
      next_x *= 2.0f;
      next_y *= 2.0f;
    }

    // The `from` window: its interpolated intensities and derivatives, and their gradient matrix.
    const float corner_x = from_x * scale - half, corner_y = from_y * scale - half;
    int ix = 0, iy = 0;
    const int from_border =
        v.from_image.border < v.from_deriv.border ? v.from_image.border : v.from_deriv.border;
    if (!LkFloor(corner_x, corner_y, &ix, &iy) ||
        !LkWindowFits(ix, iy, window, v.from_deriv.cols, v.from_deriv.rows, from_border)) {
      if (level == 0) {
        result.status = 0;
        result.error = 0.0f;
      }
      continue;
    }
    LkWeights w =
        LkBilinearWeights(corner_x - static_cast<float>(ix), corner_y - static_cast<float>(iy));
    int64_t a11 = 0, a12 = 0, a22 = 0;
    {
      const uint8_t* image = v.from_image.origin + iy * v.from_image.step + ix;
      const int image_step = v.from_image.step;
      const int16_t* deriv = v.from_deriv.origin + iy * v.from_deriv.step + 2 * ix;
      const int deriv_step = v.from_deriv.step;
      LkForEachPixel(window, lanes.first, lanes.stride, [&](int x, int y, int k) {
        image_window[k] =
            static_cast<int16_t>(LkSampleImage(image + y * image_step + x, image_step, w));
        int dx = 0, dy = 0;
        LkSampleDeriv(deriv + y * deriv_step + 2 * x, deriv_step, w, &dx, &dy);
        deriv_window[2 * k] = static_cast<int16_t>(dx);
        deriv_window[2 * k + 1] = static_cast<int16_t>(dy);
        a11 += dx * dx;
        a12 += dx * dy;
        a22 += dy * dy;
      });
    }
    const float A11 = static_cast<float>(lanes.Sum(a11)) * kLkSumScale;
    const float A12 = static_cast<float>(lanes.Sum(a12)) * kLkSumScale;
    const float A22 = static_cast<float>(lanes.Sum(a22)) * kLkSumScale;
    const float det = LkMul(A11, A22) - LkMul(A12, A12);
    const float spread = LkMul(A11 - A22, A11 - A22) + LkMul(LkMul(4.0f, A12), A12);
    const float min_eigen = (A22 + A11 - sqrtf(spread)) / static_cast<float>(2 * area);
    if (min_eigen < s.min_eigen || det < 1.1920928955078125e-07f /* FLT_EPSILON */) {
      if (level == 0) {
        result.status = 0;
        result.error = 0.0f;
      }
      continue;
    }
    const float inv_det = 1.0f / det;

    // Iterate the window corner in `to`.
    float at_x = next_x - half, at_y = next_y - half;
    float prev_step_x = 0.0f, prev_step_y = 0.0f;
    for (int j = 0; j < s.max_iterations; ++j) {
      int jx = 0, jy = 0;
      if (!LkFloor(at_x, at_y, &jx, &jy) ||
          !LkWindowFits(jx, jy, window, v.to_image.cols, v.to_image.rows, v.to_image.border)) {
        if (level == 0) {
          result.status = 0;
          result.error = 0.0f;
        }
        break;
      }
      w = LkBilinearWeights(at_x - static_cast<float>(jx), at_y - static_cast<float>(jy));
      const uint8_t* image = v.to_image.origin + jy * v.to_image.step + jx;
      const int image_step = v.to_image.step;
      int64_t b1 = 0, b2 = 0;
      LkForEachPixel(window, lanes.first, lanes.stride, [&](int x, int y, int k) {
        const int diff = LkSampleImage(image + y * image_step + x, image_step, w) - image_window[k];
        b1 += diff * deriv_window[2 * k];
        b2 += diff * deriv_window[2 * k + 1];
      });
      const float B1 = static_cast<float>(lanes.Sum(b1)) * kLkSumScale;
      const float B2 = static_cast<float>(lanes.Sum(b2)) * kLkSumScale;
      const float step_x = LkMul(LkMul(A12, B2) - LkMul(A22, B1), inv_det);
      const float step_y = LkMul(LkMul(A12, B1) - LkMul(A11, B2), inv_det);
      at_x += step_x;
      at_y += step_y;
      next_x = at_x + half;
      next_y = at_y + half;
      const double dx = step_x, dy = step_y;
      if (LkMul(dx, dx) + LkMul(dy, dy) <= s.epsilon_sq) break;
      if (j > 0 && fabsf(step_x + prev_step_x) < 0.01 && fabsf(step_y + prev_step_y) < 0.01) {
        // Oscillating about the optimum: settle half way.
        next_x -= LkMul(step_x, 0.5f);
        next_y -= LkMul(step_y, 0.5f);
        break;
      }
      prev_step_x = step_x;
      prev_step_y = step_y;
    }

    // The match error of the final position, on level 0 of a found point.
    if (level == 0 && result.status) {
      const float err_x = next_x - half, err_y = next_y - half;
      int ex = 0, ey = 0;
      if (!LkFloor(err_x, err_y, &ex, &ey) ||
          !LkWindowFits(ex, ey, window, v.to_image.cols, v.to_image.rows, v.to_image.border)) {
        result.status = 0;
        result.error = 0.0f;
        continue;
      }
      w = LkBilinearWeights(err_x - static_cast<float>(ex), err_y - static_cast<float>(ey));
      const uint8_t* image = v.to_image.origin + ey * v.to_image.step + ex;
      const int image_step = v.to_image.step;
      int64_t sum = 0;
      LkForEachPixel(window, lanes.first, lanes.stride, [&](int x, int y, int k) {
        const int diff = LkSampleImage(image + y * image_step + x, image_step, w) - image_window[k];
        sum += diff < 0 ? -diff : diff;
      });
      result.error = static_cast<float>(lanes.Sum(sum)) / static_cast<float>(32 * area);
    }
  }
  result.x = next_x;
  result.y = next_y;
  return result;
}

}  // namespace pcr::gpu
