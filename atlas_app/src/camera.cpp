#include "softatlas/app/camera.hpp"

#include <Eigen/Geometry>
#include <cmath>

namespace softatlas::app {
namespace {
constexpr float kDeg = 3.14159265358979f / 180.0f;
}

Eigen::Vector3f Camera::eye() const {
  const float yaw = yaw_deg * kDeg, pitch = pitch_deg * kDeg;
  return target +
         distance * Eigen::Vector3f(std::sin(yaw) * std::cos(pitch), std::cos(yaw) * std::cos(pitch), std::sin(pitch));
}

Eigen::Matrix4f Camera::view() const {
  const Eigen::Vector3f e = eye();
  const Eigen::Vector3f f = (target - e).normalized();
  Eigen::Vector3f up(0, 0, 1);
  if (std::abs(f.dot(up)) > 0.999f) up = Eigen::Vector3f(0, 1, 0);  // looking along z
  const Eigen::Vector3f s = f.cross(up).normalized();
  const Eigen::Vector3f u = s.cross(f);
  Eigen::Matrix4f m = Eigen::Matrix4f::Identity();
  m.block<1, 3>(0, 0) = s.transpose();
  m.block<1, 3>(1, 0) = u.transpose();
  m.block<1, 3>(2, 0) = -f.transpose();
  m(0, 3) = -s.dot(e);
  m(1, 3) = -u.dot(e);
  m(2, 3) = f.dot(e);
  return m;
}

Eigen::Matrix4f Camera::projection() const {
  const float aspect = static_cast<float>(width) / static_cast<float>(height);
  const float t = 1.0f / std::tan(0.5f * fov_y_deg * kDeg);
  const float n = near_plane(), f = far_plane();
  Eigen::Matrix4f p = Eigen::Matrix4f::Zero();
  p(0, 0) = t / aspect;
  p(1, 1) = t;
  p(2, 2) = (f + n) / (n - f);
  p(2, 3) = 2.0f * f * n / (n - f);
  p(3, 2) = -1.0f;
  return p;
}

void Camera::ray(float px, float py, Eigen::Vector3f& origin, Eigen::Vector3f& dir) const {
  const float ndc_x = 2.0f * px / static_cast<float>(width) - 1.0f;
  const float ndc_y = 1.0f - 2.0f * py / static_cast<float>(height);
  const Eigen::Matrix4f inv = (projection() * view()).inverse();
  Eigen::Vector4f a = inv * Eigen::Vector4f(ndc_x, ndc_y, -1.0f, 1.0f);
  Eigen::Vector4f b = inv * Eigen::Vector4f(ndc_x, ndc_y, 1.0f, 1.0f);
  const Eigen::Vector3f pa = a.head<3>() / a.w(), pb = b.head<3>() / b.w();
  origin = eye();
  dir = (pb - pa).normalized();
}

bool Camera::project(const Eigen::Vector3f& p, float& px, float& py) const {
  const Eigen::Vector4f c = projection() * view() * Eigen::Vector4f(p.x(), p.y(), p.z(), 1.0f);
  if (c.w() <= 1e-6f) return false;
  px = (c.x() / c.w() * 0.5f + 0.5f) * static_cast<float>(width);
  py = (0.5f - c.y() / c.w() * 0.5f) * static_cast<float>(height);
  return true;
}

void Camera::frame(const Eigen::Vector3f& lo, const Eigen::Vector3f& hi) {
  target = 0.5f * (lo + hi);
  const float radius = 0.5f * (hi - lo).norm();
  const float aspect = static_cast<float>(width) / static_cast<float>(height);
  const float half = 0.5f * fov_y_deg * kDeg;
  const float fit = std::min(std::tan(half), std::tan(half) * aspect);
  distance = radius / fit * 1.05f;
}

bool Camera::set_view(const std::string& name) {
  if (name == "anterior") {
    yaw_deg = 0;
    pitch_deg = 0;
  } else if (name == "posterior") {
    yaw_deg = 180;
    pitch_deg = 0;
  } else if (name == "right") {
    yaw_deg = 90;
    pitch_deg = 0;
  } else if (name == "left") {
    yaw_deg = -90;
    pitch_deg = 0;
  } else if (name == "superior") {
    yaw_deg = 0;
    pitch_deg = 89;
  } else if (name == "inferior") {
    yaw_deg = 0;
    pitch_deg = -89;
  } else
    return false;
  return true;
}

}  // namespace softatlas::app
