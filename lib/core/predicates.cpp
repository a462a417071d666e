#include "qota/predicates.hpp"

#include <algorithm>
#include <cmath>

namespace qota {
namespace {

// Error-free transformations: a + b == s + e and a * b == p + e exactly (round to nearest).
// These rely on strict IEEE evaluation; the library is never built with -ffast-math.
inline void twoSum(double a, double b, double& s, double& e) {
  s = a + b;
  const double bv = s - a;
  const double av = s - bv;
  e = (a - av) + (b - bv);
}

inline void twoProduct(double a, double b, double& p, double& e) {
  p = a * b;
  e = std::fma(a, b, -p);
}

// Adds b to the non-overlapping expansion e[0..n) (increasing magnitude), writing the result to
// e in place; returns the new length (n + 1). Zero components are kept; they do not change the sign.
inline int growExpansion(double* e, int n, double b) {
  double q = b;
  for (int i = 0; i < n; ++i) {
    double s, h;
    twoSum(q, e[i], s, h);
    e[i] = h;
    q = s;
  }
  e[n] = q;
  return n + 1;
}

}  // namespace

namespace {

// The sign of the expansion e[0..n): that of its largest nonzero component.
int signOf(const double* e, int n) {
  for (int i = n - 1; i >= 0; --i) {
    if (e[i] > 0) return 1;
    if (e[i] < 0) return -1;
  }
  return 0;
}

}  // namespace

int orient2dSignExact(Point2 a, Point2 b, Point2 c) {
  // When the four differences are exact (points of one grid, or near each other: the usual case
  // here, such as collinear points on a raster's rows), orient2d is (a-c)u (b-c)v - (a-c)v (b-c)u
  // exactly: two exact products, an expansion of four terms instead of twelve.
  double du1, dv2, dv1, du2, t0, t1, t2, t3;
  twoSum(a.u, -c.u, du1, t0), twoSum(b.v, -c.v, dv2, t1);
  twoSum(a.v, -c.v, dv1, t2), twoSum(b.u, -c.u, du2, t3);
  if (t0 == 0 && t1 == 0 && t2 == 0 && t3 == 0) {
    double p1, q1, p2, q2;
    twoProduct(du1, dv2, p1, q1);
    twoProduct(dv1, du2, p2, q2);
    if (p1 == p2 && q1 == q2) return 0;
    double e[4];
    int n = 0;
    for (double x : {q1, -q2, p1, -p2}) n = growExpansion(e, n, x);
    return signOf(e, n);
  }
  // Exact: orient2d = au*bv - au*cv - cu*bv - av*bu + av*cu + cv*bu  (the cu*cv terms cancel).
  const double f[6][2] = {{a.u, b.v}, {-a.u, c.v}, {-c.u, b.v}, {-a.v, b.u}, {a.v, c.u}, {c.v, b.u}};
  double e[13];
  int n = 0;
  for (const auto& pr : f) {
    double p, err;
    twoProduct(pr[0], pr[1], p, err);
    n = growExpansion(e, n, err);
    n = growExpansion(e, n, p);
  }
  return signOf(e, n);
}

int orient3dSign(const double a[3], const double b[3], const double d[3]) {
  // Fast filter: three rounded 2x2 minors, a rounded dot product; 8 ulps of the permanent bound
  // the error of the five roundings in each term.
  const double m0 = b[1] * d[2] - b[2] * d[1], m1 = b[2] * d[0] - b[0] * d[2], m2 = b[0] * d[1] - b[1] * d[0];
  const double det = a[0] * m0 + a[1] * m1 + a[2] * m2;
  const double permanent = std::fabs(a[0]) * (std::fabs(b[1] * d[2]) + std::fabs(b[2] * d[1])) +
                           std::fabs(a[1]) * (std::fabs(b[2] * d[0]) + std::fabs(b[0] * d[2])) +
                           std::fabs(a[2]) * (std::fabs(b[0] * d[1]) + std::fabs(b[1] * d[0]));
  const double bound = 8.0 * 1.1102230246251565e-16 * permanent;
  if (det > bound) return 1;
  if (det < -bound) return -1;

  // det = sum over the six permutations (i, j, k) of sign * a_i b_j d_k. Each triple product is
  // exact as four terms: b_j d_k = p + e, then a_i p and a_i e each split again.
  static constexpr int kTerms[6][4] = {{0, 1, 2, 1},  {0, 2, 1, -1}, {1, 2, 0, 1},
                                       {1, 0, 2, -1}, {2, 0, 1, 1},  {2, 1, 0, -1}};
  double e[25];
  int n = 0;
  for (const auto& t : kTerms) {
    double p, pe;
    twoProduct(b[t[1]], d[t[2]], p, pe);
    const double ai = t[3] > 0 ? a[t[0]] : -a[t[0]];
    double q[4];
    twoProduct(ai, pe, q[1], q[0]);
    twoProduct(ai, p, q[3], q[2]);
    for (double x : q) n = growExpansion(e, n, x);
  }
  for (int i = n - 1; i >= 0; --i) {
    if (e[i] > 0) return 1;
    if (e[i] < 0) return -1;
  }
  return 0;
}

bool segmentsMeet(Point2 a, Point2 b, Point2 c, Point2 d) {
  // (p collinear with xy: within its box is on it.)
  const auto on = [](Point2 x, Point2 y, Point2 p) {
    return std::min(x.u, y.u) <= p.u && p.u <= std::max(x.u, y.u) && std::min(x.v, y.v) <= p.v &&
           p.v <= std::max(x.v, y.v);
  };
  const int d1 = orient2dSign(c, d, a), d2 = orient2dSign(c, d, b);
  const int d3 = orient2dSign(a, b, c), d4 = orient2dSign(a, b, d);
  if (d1 * d2 < 0 && d3 * d4 < 0) return true;
  return (d1 == 0 && on(c, d, a)) || (d2 == 0 && on(c, d, b)) || (d3 == 0 && on(a, b, c)) || (d4 == 0 && on(a, b, d));
}

}  // namespace qota
