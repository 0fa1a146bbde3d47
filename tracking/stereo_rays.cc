#include "tracking/stereo_rays.h"

namespace hmc {

Ray3 PixelRay(const HelmetCamera& camera, const Vec2& pixel) {
  Ray3 ray;
  Vec3 bearing;
  if (!camera.camera.Unproject(pixel, &bearing)) return ray;
  const Rigid3 helmet_from_cam = camera.cam_from_helmet.inverse();
  ray.origin = helmet_from_cam.translation();
  ray.direction = (helmet_from_cam.linear() * bearing).normalized();
  ray.ok = true;
  return ray;
}

RayApproach ClosestApproach(const Ray3& r0, const Ray3& r1) {
  RayApproach out;
  if (!r0.ok || !r1.ok) return out;
  const Vec3 w = r0.origin - r1.origin;
  const double a = r0.direction.dot(r0.direction), b = r0.direction.dot(r1.direction);
  const double c = r1.direction.dot(r1.direction), d = r0.direction.dot(w);
  const double e = r1.direction.dot(w);
  const double den = a * c - b * b;
  if (!(den > 1e-12)) return out;
  out.s0 = (b * e - c * d) / den;
  out.s1 = (a * e - b * d) / den;
  const Vec3 p0 = r0.origin + out.s0 * r0.direction, p1 = r1.origin + out.s1 * r1.direction;
  out.gap = (p0 - p1).norm();
  out.midpoint = 0.5 * (p0 + p1);
  out.ok = out.s0 > 0 && out.s1 > 0;
  return out;
}

}  // namespace hmc
