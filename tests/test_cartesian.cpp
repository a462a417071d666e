#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <random>

#include "qota/cartesian.hpp"
#include "qota/error.hpp"

namespace {

using qota::CartesianMapping;

TEST(CartesianMapping, VerticalGravityIsAnExactTranslation) {
  const CartesianMapping m(Eigen::Vector3d(0, 0, -9.81), Eigen::Vector3d(557805, 5122005, 0));
  EXPECT_TRUE(m.vertical());
  const Eigen::Vector3d p(557820.123456789, 5122019.987654321, 1234.5);
  const Eigen::Vector3d q = m.toMapped(p);
  EXPECT_EQ(q, p - m.origin());
  EXPECT_EQ(m.toWorld(q), (p - m.origin()) + m.origin());
  EXPECT_EQ(m.gravity(), Eigen::Vector3d(0, 0, -1));
}

TEST(CartesianMapping, GravityMapsToMinusZ) {
  std::mt19937_64 rng(42);
  std::normal_distribution<double> n(0, 1);
  for (int i = 0; i < 1000; ++i) {
    const Eigen::Vector3d g(n(rng), n(rng), n(rng));
    const CartesianMapping m(g);
    const Eigen::Vector3d down = m.rotation() * g.normalized();
    EXPECT_NEAR(down.x(), 0, 1e-14);
    EXPECT_NEAR(down.y(), 0, 1e-14);
    EXPECT_NEAR(down.z(), -1, 1e-14);
    EXPECT_NEAR(m.rotation().determinant(), 1, 1e-14);  // a rotation, right-handed
    // The line for (u, v) runs along gravity and has h = 0 at its origin.
    const auto line = m.line(1.5, -2.5);
    EXPECT_NEAR(m.toMapped(line.origin).z(), 0, 1e-12);
    EXPECT_NEAR(m.toMapped(line.origin + 3.0 * line.down).z(), -3, 1e-12);
  }
}

TEST(CartesianMapping, AntiparallelGravity) {
  const CartesianMapping m(Eigen::Vector3d(0, 0, 2));
  const Eigen::Vector3d down = m.rotation() * Eigen::Vector3d(0, 0, 1);
  EXPECT_NEAR(down.z(), -1, 1e-15);
}

TEST(CartesianMapping, RoundTrip) {
  std::mt19937_64 rng(9);
  std::normal_distribution<double> n(0, 1);
  std::uniform_real_distribution<double> big(-1e7, 1e7);
  for (int i = 0; i < 100000; ++i) {
    const CartesianMapping m(Eigen::Vector3d(n(rng), n(rng), n(rng)), Eigen::Vector3d(big(rng), big(rng), big(rng)));
    const Eigen::Vector3d p = m.origin() + Eigen::Vector3d(n(rng), n(rng), n(rng)) * 1000.0;
    const Eigen::Vector3d back = m.toWorld(m.toMapped(p));
    ASSERT_LE((back - p).norm(), 1e-12 * (p.norm() + 1.0)) << i;
  }
}

TEST(CartesianMapping, RejectsBadGravityAndOrigin) {
  EXPECT_THROW((void)CartesianMapping(Eigen::Vector3d::Zero()), qota::Error);
  EXPECT_THROW(CartesianMapping(Eigen::Vector3d(0, NAN, -1)), qota::Error);
  EXPECT_THROW(CartesianMapping(Eigen::Vector3d(0, 0, -1), Eigen::Vector3d(INFINITY, 0, 0)), qota::Error);
}

}  // namespace
