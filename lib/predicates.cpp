#include "qota/predicates.hpp"

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

int orient2dSign(Point2 a, Point2 b, Point2 c) {
  // Fast filter: the rounded determinant is exact in sign when it exceeds its error bound.
  const double left = (a.u - c.u) * (b.v - c.v);
  const double right = (a.v - c.v) * (b.u - c.u);
  const double det = left - right;
  // 8 units in the last place of the magnitude sum bounds the error of the three roundings of the
  // differences, two products and the subtraction (Shewchuk's bound is (3 + 16u)u).
  const double bound = 8.0 * 1.1102230246251565e-16 * (std::fabs(left) + std::fabs(right));
  if (det > bound) return 1;
  if (det < -bound) return -1;

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
  for (int i = n - 1; i >= 0; --i) {
    if (e[i] > 0) return 1;
    if (e[i] < 0) return -1;
  }
  return 0;
}

}  // namespace qota
