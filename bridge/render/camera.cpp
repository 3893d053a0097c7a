#include "render/camera.h"

#include <cmath>

#include "glimmer/sampling.h"

namespace glimmer::render {

// Pinhole camera: looks along +Z of camera space, +Y up, fov across the
// shorter image side (Cycles' viewplane).
CameraFrame camera_frame(const scene::Camera &cam, int width, int height) {
  CameraFrame f;
  f.width = width;
  f.height = height;
  const float aspect = static_cast<float>(width) / static_cast<float>(height);
  if (width >= height) { f.half_w = aspect; f.half_h = 1.0f; }
  else { f.half_w = 1.0f; f.half_h = 1.0f / aspect; }
  const float t = std::tan(0.5f * cam.fov);
  f.tan_half_fov = t;
  f.dvx = Vec3(2.0f / width * f.half_w * t, 0.0f, 0.0f);
  f.dvy = Vec3(0.0f, -2.0f / height * f.half_h * t, 0.0f);
  f.dvx_world = cam.camera_to_world.vector(f.dvx);
  f.dvy_world = cam.camera_to_world.vector(f.dvy);
  f.origin = cam.camera_to_world.point(Vec3(0.0f));
  f.view_axis = normalize(cam.camera_to_world.vector(Vec3(0, 0, 1)));
  return f;
}

// Camera ray through film position (x, y); (lens_u, lens_v) picks the point on the thin-lens aperture.
void camera_ray(const scene::Camera &cam, const CameraFrame &f, float x, float y, Vec3 &org, Vec3 &dir,
                Differentials &rd, float &dir_z, float lens_u, float lens_v) {
  const float t = f.tan_half_fov;
  const float sx = (2.0f * x / f.width - 1.0f) * f.half_w * t;
  const float sy = (1.0f - 2.0f * y / f.height) * f.half_h * t;
  const Vec3 v(sx, sy, 1.0f);
  // World-space direction and its derivative d(normalize(v))/dx = (v.v dv - v (v.dv)) / |v|^3.
  const Vec3 vw = cam.camera_to_world.vector(v);
  const float lw = length(vw);
  dir = vw / lw;
  auto ddir = [&](const Vec3 &dv) { return (dv * dot(vw, vw) - vw * dot(vw, dv)) / (lw * lw * lw); };
  rd.dDdx = ddir(f.dvx_world);
  rd.dDdy = ddir(f.dvy_world);
  rd.dPdx = rd.dPdy = Vec3(0.0f);
  org = f.origin;
  if (cam.aperture_size > 0.0f) {
    // Cycles' thin lens (kernel/camera/camera.h): the point on the plane z = focaldistance seen through the
    // pinhole, reached from a uniform point on the aperture disk of radius aperturesize. The pixel's
    // differentials stay the pinhole's (at depth z every lens point's ray moves by z dv per pixel).
    float lx, ly;
    sample_uniform_disk_concentric(lens_u, lens_v, lx, ly);
    const Vec3 lens_point(lx * cam.aperture_size, ly * cam.aperture_size, 0.0f);
    const Vec3 focus_point = v * cam.focal_distance;  // v.z = 1
    const Vec3 w = cam.camera_to_world.vector(focus_point - lens_point);
    dir = normalize(w);
    org = cam.camera_to_world.point(lens_point);
    // The aperture's share: moving the lens point by A along camera x moves the origin by A x and w by
    // -A x; P(z) = (z / f) focus + (1 - z / f) lens spreads by A (1 - z / f) at depth z.
    const Vec3 ax = cam.camera_to_world.vector(Vec3(cam.aperture_size, 0.0f, 0.0f));
    const Vec3 ay = cam.camera_to_world.vector(Vec3(0.0f, cam.aperture_size, 0.0f));
    const float l = length(w);
    auto ddir_lens = [&](const Vec3 &dw) { return (dw * dot(w, w) - w * dot(w, dw)) / (l * l * l); };
    rd.dPdlx = ax;
    rd.dPdly = ay;
    rd.dDdlx = ddir_lens(-ax);
    rd.dDdly = ddir_lens(-ay);
    rd.lens = true;
  }
  // Depth of the first hit is measured along camera +Z in world units.
  dir_z = dot(dir, f.view_axis);
}

void fold_lens_differentials(Differentials &rd, const Vec3 &D, float t, const Vec3 &Ng) {
  if (!rd.lens) return;
  rd.lens = false;
  auto fold = [&](Vec3 &dP, Vec3 &dD, const Vec3 &dPl, const Vec3 &dDl) {
    const Vec3 pixel = footprint_on_plane(dP, dD, D, t, Ng), lens = footprint_on_plane(dPl, dDl, D, t, Ng);
    const float sign = dot(pixel, lens) >= 0.0f ? 1.0f : -1.0f;
    dP += dPl * sign;
    dD += dDl * sign;
  };
  fold(rd.dPdx, rd.dDdx, rd.dPdlx, rd.dDdlx);
  fold(rd.dPdy, rd.dDdy, rd.dPdly, rd.dDdly);
}

// Reflect or refract the direction differentials (Igehy 1999, eq. 14-15, 18-19).
void propagate_specular(Differentials &rd, const Vec3 &D, const Vec3 &wo, const Vec3 &N, const Vec3 &Ng,
                        const Vec3 &dn1, const Vec3 &dn2, float eta) {
  const float DN = dot(D, N);
  const bool reflect_dir = dot(wo, Ng) > 0.0f;  // Ng faces the incoming side
  auto one = [&](const Vec3 &dD, const Vec3 &dN) -> Vec3 {
    const float dDN = dot(dD, N) + dot(D, dN);
    if (reflect_dir) return dD - 2.0f * (N * dDN + dN * DN);
    // Refraction: wo = mu_eta * D - mu * N.
    const Vec3 Dt = D - N * DN, Tt = wo - N * dot(wo, N);
    float ratio = length(Dt) > 1e-4f ? length(Tt) / length(Dt) : (eta > 0.0f ? 1.0f / eta : 1.0f);
    if (!std::isfinite(ratio) || ratio <= 0.0f) ratio = 1.0f;
    const float TN = dot(wo, N);
    const float mu = ratio * DN - TN;
    const float dmu = std::fabs(TN) > 1e-6f ? (ratio - ratio * ratio * DN / TN) * dDN : 0.0f;
    return dD * ratio - (dN * mu + N * dmu);
  };
  rd.dDdx = one(rd.dDdx, dn1);
  rd.dDdy = one(rd.dDdy, dn2);
  if (!is_finite(rd.dDdx) || !is_finite(rd.dDdy)) rd.dDdx = rd.dDdy = Vec3(0.0f);
}

}  // namespace glimmer::render
