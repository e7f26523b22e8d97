// Orbit camera in organ-set coordinates (mm, RAS: +x right, +y anterior, +z superior of the
// patient). yaw 0 looks at the patient from the front (anterior view).
#pragma once

#include <Eigen/Core>
#include <string>

namespace softatlas::app {

struct Camera {
  Eigen::Vector3f target{0, 0, 0};
  float yaw_deg = 0.0f;     // about +z; 0: eye on +y (anterior), 90: eye on +x (patient's right)
  float pitch_deg = 10.0f;  // elevation above the axial plane
  float distance = 500.0f;  // mm
  float fov_y_deg = 35.0f;
  int width = 1280, height = 720;

  Eigen::Vector3f eye() const;
  Eigen::Matrix4f view() const;
  Eigen::Matrix4f projection() const;
  // Near/far planes follow the distance so that the depth buffer keeps its precision.
  float near_plane() const { return distance * 0.05f; }
  float far_plane() const { return distance * 4.0f; }
  // A ray through pixel (px, py), top-left origin, pixel centres at +0.5; dir is unit length.
  void ray(float px, float py, Eigen::Vector3f& origin, Eigen::Vector3f& dir) const;
  // Pixel coordinates (top-left origin) of a world point; false if it is behind the camera.
  bool project(const Eigen::Vector3f& p, float& px, float& py) const;
  // Fits an axis-aligned box (keeps the view direction).
  void frame(const Eigen::Vector3f& lo, const Eigen::Vector3f& hi);
  // anterior | posterior | left | right | superior | inferior; false for an unknown name.
  bool set_view(const std::string& name);
};

}  // namespace softatlas::app
