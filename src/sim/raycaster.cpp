#include "sim/raycaster.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <opencv2/core.hpp>

#include "sim/instances.h"
#include "sim/shading.h"

namespace pcr::sim {
namespace {

constexpr double kNearM = 0.05;
constexpr double kFarM = 3000.0;
constexpr int kTile = 32;

struct PreparedBox {
  const BoxPrim* box;
  double m[9];  // local_from_cam rotation, row-major
  double o[3];  // camera centre in the box frame
  double h[3];
  double min_depth;
  int x0, y0, x1, y1;  // inclusive pixel rectangle
  float light[6];
};

Eigen::Matrix3d RotY(double yaw) {
  const double c = std::cos(yaw), s = std::sin(yaw);
  Eigen::Matrix3d r;
  r << c, 0, s, 0, 1, 0, -s, 0, c;
  return r;
}

// Fills `out` and returns false when the box is outside the view.
bool Prepare(const BoxPrim& box, const ViewInput& in, PreparedBox* out) {
  const Eigen::Matrix3d r_box = RotY(box.yaw_rad);
  const Eigen::Matrix3d local_from_cam = r_box.transpose() * in.map_from_cam_rotation;
  const Eigen::Vector3d o_local = r_box.transpose() * (in.cam_in_map - box.center);
  const Eigen::Matrix3d cam_from_local = local_from_cam.transpose();
  const Eigen::Vector3d h = box.half_m;
  Eigen::Vector3d corners[8];
  for (int i = 0; i < 8; ++i) {
    const Eigen::Vector3d c((i & 1) ? h.x() : -h.x(), (i & 2) ? h.y() : -h.y(),
                            (i & 4) ? h.z() : -h.z());
    corners[i] = cam_from_local * (c - o_local);
  }
  const PinholeCamera& cam = in.camera;
  double min_z = std::numeric_limits<double>::infinity();
  double u0 = std::numeric_limits<double>::infinity(), u1 = -u0, v0 = u0, v1 = -u0;
  auto add = [&](const Eigen::Vector3d& p) {
    const double u = cam.fx * p.x() / p.z() + cam.cx, v = cam.fy * p.y() / p.z() + cam.cy;
    u0 = std::min(u0, u);
    u1 = std::max(u1, u);
    v0 = std::min(v0, v);
    v1 = std::max(v1, v);
    min_z = std::min(min_z, p.z());
  };
  int in_front = 0;
  for (const auto& p : corners)
    if (p.z() >= kNearM) {
      add(p);
      ++in_front;
    }
  if (in_front == 0) return false;
  if (in_front < 8) {  // clip the 12 edges at the near plane
    for (int i = 0; i < 8; ++i)
      for (int bit = 1; bit < 8; bit <<= 1) {
        const int j = i | bit;
        if (j == i) continue;
        const Eigen::Vector3d& a = corners[i];
        const Eigen::Vector3d& b = corners[j];
        if ((a.z() >= kNearM) == (b.z() >= kNearM)) continue;
        const double t = (kNearM - a.z()) / (b.z() - a.z());
        add(a + t * (b - a));
      }
  }
  if (min_z > kFarM) return false;
  const double big = 1e7;
  u0 = std::clamp(u0, -big, big);
  u1 = std::clamp(u1, -big, big);
  v0 = std::clamp(v0, -big, big);
  v1 = std::clamp(v1, -big, big);
  out->x0 = std::max(0, static_cast<int>(std::floor(u0)) - 1);
  out->x1 = std::min(cam.width_px - 1, static_cast<int>(std::ceil(u1)) + 1);
  out->y0 = std::max(0, static_cast<int>(std::floor(v0)) - 1);
  out->y1 = std::min(cam.height_px - 1, static_cast<int>(std::ceil(v1)) + 1);
  if (out->x0 > out->x1 || out->y0 > out->y1) return false;
  out->box = &box;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) out->m[3 * r + c] = local_from_cam(r, c);
    out->o[r] = o_local[r];
    out->h[r] = h[r];
  }
  out->min_depth = std::max(min_z, kNearM);
  const double c = std::cos(box.yaw_rad), s = std::sin(box.yaw_rad);
  out->light[0] = static_cast<float>(LightFactor(-c, 0, s));
  out->light[1] = static_cast<float>(LightFactor(c, 0, -s));
  out->light[2] = static_cast<float>(LightFactor(0, -1, 0));
  out->light[3] = static_cast<float>(LightFactor(0, 1, 0));
  out->light[4] = static_cast<float>(LightFactor(-s, 0, -c));
  out->light[5] = static_cast<float>(LightFactor(s, 0, c));
  return true;
}

// Slab test; returns the entry distance (ray parameter = depth, as d has z_cam = 1) and face.
inline bool Intersect(const PreparedBox& b, const double d[3], double t_max, double* t_hit,
                      int* face) {
  double t_min = kNearM;
  int entry = -1;
  for (int k = 0; k < 3; ++k) {
    if (std::abs(d[k]) < 1e-15) {
      if (std::abs(b.o[k]) > b.h[k]) return false;
      continue;
    }
    const double inv = 1.0 / d[k];
    double t0 = (-b.h[k] - b.o[k]) * inv, t1 = (b.h[k] - b.o[k]) * inv;
    int f0 = 2 * k;
    if (t0 > t1) {
      std::swap(t0, t1);
      f0 = 2 * k + 1;
    }
    if (t0 > t_min) {
      t_min = t0;
      entry = f0;
    }
    t_max = std::min(t_max, t1);
    if (t_min > t_max) return false;
  }
  if (entry < 0) return false;  // camera inside the box or entry before the near plane
  *t_hit = t_min;
  *face = entry;
  return true;
}

}  // namespace

void RenderView(const ViewInput& in, ViewOutput* out) {
  const PinholeCamera& cam = in.camera;
  const int width = cam.width_px, height = cam.height_px;
  out->radiance.create(height, width, CV_32FC1);
  out->instance.create(height, width, CV_16UC1);
  out->depth.create(height, width, CV_32FC1);

  std::vector<PreparedBox> prepared;
  prepared.reserve(in.boxes->size());
  for (const BoxPrim& box : *in.boxes) {
    PreparedBox p;
    if (Prepare(box, in, &p)) prepared.push_back(p);
  }
  std::stable_sort(
      prepared.begin(), prepared.end(),
      [](const PreparedBox& a, const PreparedBox& b) { return a.min_depth < b.min_depth; });

  const int tiles_x = (width + kTile - 1) / kTile, tiles_y = (height + kTile - 1) / kTile;
  const int num_tiles = tiles_x * tiles_y;
  std::vector<int> offsets(num_tiles + 1, 0);
  for (const PreparedBox& p : prepared)
    for (int ty = p.y0 / kTile; ty <= p.y1 / kTile; ++ty)
      for (int tx = p.x0 / kTile; tx <= p.x1 / kTile; ++tx) ++offsets[ty * tiles_x + tx + 1];
  std::partial_sum(offsets.begin(), offsets.end(), offsets.begin());
  std::vector<int> lists(offsets.back());
  {
    std::vector<int> fill(offsets.begin(), offsets.end() - 1);
    for (size_t i = 0; i < prepared.size(); ++i) {
      const PreparedBox& p = prepared[i];
      for (int ty = p.y0 / kTile; ty <= p.y1 / kTile; ++ty)
        for (int tx = p.x0 / kTile; tx <= p.x1 / kTile; ++tx)
          lists[fill[ty * tiles_x + tx]++] = static_cast<int>(i);
    }
  }

  const Eigen::Matrix3d& rc = in.map_from_cam_rotation;
  const Eigen::Vector3d& o = in.cam_in_map;
  const double ground_light = LightFactor(0, -1, 0);
  const Eigen::Vector3d eu_map = rc.col(0) / cam.fx, ev_map = rc.col(1) / cam.fy;

  auto render_tiles = [&](const cv::Range& range) {
    for (int tile = range.start; tile < range.end; ++tile) {
      const int tx = tile % tiles_x, ty = tile / tiles_x;
      const int* list = lists.data() + offsets[tile];
      const int list_size = offsets[tile + 1] - offsets[tile];
      const int ux0 = tx * kTile, ux1 = std::min(width, ux0 + kTile);
      const int vy0 = ty * kTile, vy1 = std::min(height, vy0 + kTile);
      for (int v = vy0; v < vy1; ++v) {
        float* rad_row = out->radiance.ptr<float>(v);
        uint16_t* inst_row = out->instance.ptr<uint16_t>(v);
        float* depth_row = out->depth.ptr<float>(v);
        const double yn = (v - cam.cy) / cam.fy;
        for (int u = ux0; u < ux1; ++u) {
          const double xn = (u - cam.cx) / cam.fx;
          const Eigen::Vector3d d_map = rc * Eigen::Vector3d(xn, yn, 1.0);
          double best = std::numeric_limits<double>::infinity();
          int best_box = -1, best_face = -1;
          bool ground = false;
          if (d_map.y() > 1e-12) {
            best = -o.y() / d_map.y();
            ground = true;
          }
          for (int li = 0; li < list_size; ++li) {
            const PreparedBox& b = prepared[static_cast<size_t>(list[li])];
            if (b.min_depth >= best) break;
            if (u < b.x0 || u > b.x1 || v < b.y0 || v > b.y1) continue;
            const double d[3] = {b.m[0] * xn + b.m[1] * yn + b.m[2],
                                 b.m[3] * xn + b.m[4] * yn + b.m[5],
                                 b.m[6] * xn + b.m[7] * yn + b.m[8]};
            double t;
            int face;
            if (Intersect(b, d, best, &t, &face) && t < best) {
              best = t;
              best_box = list[li];
              best_face = face;
            }
          }
          if (best_box >= 0) {
            const PreparedBox& b = prepared[static_cast<size_t>(best_box)];
            const double d[3] = {b.m[0] * xn + b.m[1] * yn + b.m[2],
                                 b.m[3] * xn + b.m[4] * yn + b.m[5],
                                 b.m[6] * xn + b.m[7] * yn + b.m[8]};
            const double eu[3] = {b.m[0] / cam.fx, b.m[3] / cam.fx, b.m[6] / cam.fx};
            const double ev[3] = {b.m[1] / cam.fy, b.m[4] / cam.fy, b.m[7] / cam.fy};
            const int k = best_face / 2;
            const double ru = eu[k] / d[k], rv = ev[k] / d[k];
            double p[3], du[3], dv[3];
            for (int i = 0; i < 3; ++i) {
              p[i] = b.o[i] + best * d[i];
              du[i] = best * (eu[i] - d[i] * ru);
              dv[i] = best * (ev[i] - d[i] * rv);
            }
            double a, bb;
            int ia, ib;
            if (k == 0) {
              a = p[2] + b.h[2];
              bb = b.h[1] - p[1];
              ia = 2;
              ib = 1;
            } else if (k == 1) {
              a = p[0] + b.h[0];
              bb = p[2] + b.h[2];
              ia = 0;
              ib = 2;
            } else {
              a = p[0] + b.h[0];
              bb = b.h[1] - p[1];
              ia = 0;
              ib = 1;
            }
            const double wa = std::abs(du[ia]) + std::abs(dv[ia]);
            const double wb = std::abs(du[ib]) + std::abs(dv[ib]);
            const double albedo = ShadeBox(*b.box, best_face, a, bb, wa, wb);
            rad_row[u] =
                static_cast<float>(255.0 * Haze(albedo * b.light[best_face], best * d_map.norm()));
            inst_row[u] = b.box->instance_id;
            depth_row[u] = static_cast<float>(best);
          } else if (ground) {
            const double ry = eu_map.y() / d_map.y(), ryv = ev_map.y() / d_map.y();
            const Eigen::Vector3d p = o + best * d_map;
            const Eigen::Vector3d du = best * (eu_map - d_map * ry);
            const Eigen::Vector3d dv = best * (ev_map - d_map * ryv);
            const double albedo =
                ShadeGround(*in.ground, p.x(), p.z(), du.x(), du.z(), dv.x(), dv.z());
            rad_row[u] =
                static_cast<float>(255.0 * Haze(albedo * ground_light, best * d_map.norm()));
            inst_row[u] = kStaticInstanceId;
            depth_row[u] = static_cast<float>(best);
          } else {
            rad_row[u] = static_cast<float>(255.0 * SkyRadiance(-d_map.y() / d_map.norm()));
            inst_row[u] = kSkyInstanceId;
            depth_row[u] = std::numeric_limits<float>::infinity();
          }
        }
      }
    }
  };
  cv::parallel_for_(cv::Range(0, num_tiles), render_tiles);
}

}  // namespace pcr::sim
