#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "qota/predicates.hpp"

namespace {

using qota::orient2dSign;
using qota::Point2;

__extension__ typedef __int128 Int128;

// Exact reference for integer-valued coordinates: 128-bit integer arithmetic.
int exactIntegerSign(Point2 a, Point2 b, Point2 c) {
  const auto ax = static_cast<Int128>(a.u), ay = static_cast<Int128>(a.v);
  const auto bx = static_cast<Int128>(b.u), by = static_cast<Int128>(b.v);
  const auto cx = static_cast<Int128>(c.u), cy = static_cast<Int128>(c.v);
  const Int128 d = (ax - cx) * (by - cy) - (ay - cy) * (bx - cx);
  return d > 0 ? 1 : d < 0 ? -1 : 0;
}

TEST(Predicates, BasicTurns) {
  EXPECT_EQ(orient2dSign({0, 0}, {1, 0}, {0, 1}), 1);
  EXPECT_EQ(orient2dSign({0, 0}, {0, 1}, {1, 0}), -1);
  EXPECT_EQ(orient2dSign({0, 0}, {1, 1}, {2, 2}), 0);
  EXPECT_EQ(orient2dSign({0, 0}, {0, 0}, {5, 7}), 0);
}

TEST(Predicates, MatchesIntegerArithmeticOnLargeIntegers) {
  // Integers up to 2^50: the products need 101 bits, far past what doubles hold.
  std::mt19937_64 rng(12345);
  std::uniform_int_distribution<std::int64_t> coord(-(1ll << 50), 1ll << 50);
  for (int i = 0; i < 200000; ++i) {
    Point2 a{double(coord(rng)), double(coord(rng))};
    Point2 b{double(coord(rng)), double(coord(rng))};
    Point2 c;
    if (i % 2) {
      // On the line a-b or one unit off it: the hard cases.
      const std::int64_t t = coord(rng) % 1024;
      c = {a.u + t * (b.u - a.u) / 1024.0, a.v + t * (b.v - a.v) / 1024.0};
      c.u = std::nearbyint(c.u) + (i % 3 == 0 ? 1 : 0);
      c.v = std::nearbyint(c.v);
    } else {
      c = {double(coord(rng)), double(coord(rng))};
    }
    ASSERT_EQ(orient2dSign(a, b, c), exactIntegerSign(a, b, c)) << "case " << i;
  }
}

TEST(Predicates, BothExactPathsMatchIntegerArithmetic) {
  // orient2dSignExact itself (the filter sends it only the hard cases): its short path when the
  // differences are exact (near points, one grid), its full expansion when they are not (large
  // and small coordinates mixed, up to 2^61: a difference needs up to 62 bits; the products stay
  // within the reference's 128 bits).
  std::mt19937_64 rng(99);
  const auto coordinate = [&](int bits) {
    const double x = std::ldexp(static_cast<double>(static_cast<std::int64_t>(rng() >> 11)), bits - 53);
    return std::trunc(rng() % 2 ? x : -x);  // an integer below 2^bits in magnitude
  };
  int shortPath = 0;
  for (int i = 0; i < 300000; ++i) {
    const int bits = 1 + static_cast<int>(rng() % 59);
    Point2 a{coordinate(bits), coordinate(bits)}, b{coordinate(bits), coordinate(bits)};
    Point2 c{coordinate(1 + static_cast<int>(rng() % 61)), coordinate(1 + static_cast<int>(rng() % 61))};
    if (i % 3 == 0) c = {a.u + (b.u - a.u) * 2, a.v + (b.v - a.v) * 2};  // on the line, when exact
    if (i % 5 == 0) b = {a.u + 1, a.v + 1}, c = {a.u + 2, a.v + 2 + (i % 2)};
    shortPath += a.u - c.u == static_cast<double>(static_cast<Int128>(a.u) - static_cast<Int128>(c.u));
    ASSERT_EQ(qota::orient2dSignExact(a, b, c), exactIntegerSign(a, b, c))
        << "case " << i << ": " << a.u << " " << a.v << ", " << b.u << " " << b.v << ", " << c.u << " " << c.v;
  }
  EXPECT_GT(shortPath, 1000);
}

TEST(Predicates, NearlyCollinearFloatingPoints) {
  // Points nudged by one ulp across the line y = x: the naive determinant gets many wrong.
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> t(0.5, 12.0);
  int naiveWrong = 0;
  for (int i = 0; i < 100000; ++i) {
    const double x = t(rng);
    const Point2 a{0.5, 0.5}, b{12, 12};
    const Point2 on{x, x};
    const Point2 left{x, std::nextafter(x, 100.0)};
    const Point2 right{x, std::nextafter(x, -100.0)};
    ASSERT_EQ(orient2dSign(a, b, on), 0);
    ASSERT_EQ(orient2dSign(a, b, left), 1);
    ASSERT_EQ(orient2dSign(a, b, right), -1);
    // Consistency under permutation: an even permutation keeps the sign, an odd one flips it.
    ASSERT_EQ(orient2dSign(b, left, a), 1);
    ASSERT_EQ(orient2dSign(left, b, a), -1);
    const Point2 far{x + 1e6, x + 1e6 + 1e-10};
    const int s = orient2dSign(a, b, far);
    if ((qota::orient2dApprox(a, b, far) > 0 ? 1 : -1) != s) ++naiveWrong;
  }
  RecordProperty("naive_wrong", naiveWrong);
}

}  // namespace
