#pragma once
// Albedo of the synthetic world's surfaces (src/sim internal). Texture coordinates are metres on
// the surface; wa, wb the pixel footprint along them (see texture.h).
#include <vector>

#include "sim/scene.h"

namespace pcr::sim {

// Box faces: 0 -x, 1 +x, 2 -y (top, the map's y points down), 3 +y (bottom), 4 -z, 5 +z. On a
// vertical face, a runs along the face and b is the height above the box bottom; on the top and
// bottom faces (a, b) = (x, z) from the box corner.
double ShadeBox(const BoxPrim& box, int face, double a, double b, double wa, double wb);

// Ground plane (y = 0) at map point (x, z). dx_*, dz_* are the hit point's derivatives along the
// image axes (metres per pixel), for the footprint.
double ShadeGround(const Ground& ground, double x, double z, double dx_u, double dz_u, double dx_v,
                   double dz_v);

// Sky radiance (0..1) for a ray whose map-frame direction has elevation sin_elevation (up > 0).
double SkyRadiance(double sin_elevation);

// Aerial perspective: radiance seen through distance_m of haze.
double Haze(double radiance, double distance_m);

// Lambertian shading factor for a map-frame unit normal.
double LightFactor(double nx, double ny, double nz);

}  // namespace pcr::sim
