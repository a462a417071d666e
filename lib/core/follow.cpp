#include "qota/follow.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

namespace qota {

bool fitPlane(std::span<const Eigen::Vector3d> points, Eigen::Vector3d& centroid, Eigen::Vector3d& normal,
              double& rms) {
  const std::size_t n = points.size();
  if (n < 3) return false;
  centroid.setZero();
  for (const auto& p : points) centroid += p;
  centroid /= static_cast<double>(n);
  // Relative to the centroid, so planet-sized coordinates keep their precision.
  double extent = 0;
  for (const auto& p : points) extent = std::max(extent, (p - centroid).norm());
  if (!(extent > 0)) return false;
  if (n == 3) {
    normal = (points[1] - points[0]).cross(points[2] - points[0]);
    rms = 0;
  } else {
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (const auto& p : points) {
      const Eigen::Vector3d d = p - centroid;
      cov += d * d.transpose();
    }
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
    // Eigenvalues ascending: the smallest spread is the normal; the middle one must be real
    // spread, else the points lie on a line.
    if (!(eig.eigenvalues()[1] > 1e-20 * eig.eigenvalues()[2])) return false;
    normal = eig.eigenvectors().col(0);
    rms = std::sqrt(std::max(0.0, eig.eigenvalues()[0]) / static_cast<double>(n));
  }
  const double len = normal.norm();
  // Collinear: the normal is tiny against the points' spread.
  if (!(len > 1e-12 * extent * extent) && n == 3) return false;
  normal /= len;
  return true;
}

Pose poseOnPlane(const Eigen::Vector3d& position, const Eigen::Vector3d& normal, const Eigen::Vector3d& up,
                 const Eigen::Vector3d& heading) {
  // x = horizontal heading + lambda up, with lambda putting it in the plane.
  Eigen::Vector3d h = heading - heading.dot(up) * up;
  const double nu = normal.dot(up);
  Eigen::Vector3d x = h.squaredNorm() > 0 && nu != 0 ? Eigen::Vector3d(h - (h.dot(normal) / nu) * up)
                                                     : Eigen::Vector3d(normal.unitOrthogonal());
  x.normalize();
  Pose pose;
  pose.position = position;
  pose.orientation.col(0) = x;
  pose.orientation.col(1) = normal.cross(x);
  pose.orientation.col(2) = normal;
  return pose;
}

}  // namespace qota
