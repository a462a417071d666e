// The cells round a raster's inner squares that a padded track reaches: where a line of sight
// walked over the squares under it (viewshed.cpp, on an ellipsoid) can meet the border's
// triangles (the outer half pixel).
//
// Pixel coordinates here have the pixel centres at whole numbers: the inner squares are the cells
// [c, c + 1] x [r, r + 1] for 0 <= c <= width - 2, 0 <= r <= height - 2, and the ring the cells with
// c = -1 or width - 1, or r = -1 or height - 1. Each ring cell belongs to one side: the top row
// (r = -1) and the bottom (r = height - 1) by c + 1, then the left column (c = -1) and the right
// (c = width - 1) by r + 1.
#pragma once

#include <algorithm>
#include <cmath>

namespace qota::walk {

enum class Side { Top, Bottom, Left, Right };

// visit(side, k) for every ring cell whose box, widened by `pad` on every side, the track from
// (ax, ay) to (bx, by) reaches (and maybe a few more); stops and returns true when visit does.
// Why this finds them: a track's distance past a side's line is linear along it, so it comes
// within pad of that side along one stretch, and the cells it can reach on that side are those of
// the stretch's columns (rows), widened by pad.
template <class Visit>
bool forRingCells(double ax, double ay, double bx, double by, double pad, int width, int height, const Visit& visit) {
  // The parameters [u0, u1] within [0, 1] where s(u) = s0 + u (s1 - s0) is below `limit`
  // (below) or above it; false when there are none.
  const auto stretch = [](double s0, double s1, double limit, bool below, double& u0, double& u1) {
    const double step = s1 - s0;
    u0 = 0, u1 = 1;
    if (step == 0) return below ? s0 < limit : s0 > limit;
    const double u = (limit - s0) / step;
    if ((step > 0) == below) {
      u1 = std::min(1.0, u);
    } else {
      u0 = std::max(0.0, u);
    }
    return u0 <= u1;
  };
  // The cells along one side over the other coordinate's range t(u0) to t(u1), widened by pad.
  const auto along = [&](Side side, double t0, double t1, double u0, double u1, int last) {
    const double ta = t0 + u0 * (t1 - t0), tb = t0 + u1 * (t1 - t0);
    const int first = std::max(-1, static_cast<int>(std::floor(std::min(ta, tb) - pad)));
    const int end = std::min(last, static_cast<int>(std::floor(std::max(ta, tb) + pad)));
    for (int k = first; k <= end; ++k) {
      if (visit(side, k + 1)) return true;
    }
    return false;
  };
  double u0, u1;
  if (stretch(ay, by, pad, true, u0, u1) && along(Side::Top, ax, bx, u0, u1, width - 1)) return true;
  if (stretch(ay, by, height - 1 - pad, false, u0, u1) && along(Side::Bottom, ax, bx, u0, u1, width - 1)) return true;
  if (stretch(ax, bx, pad, true, u0, u1) && along(Side::Left, ay, by, u0, u1, height - 1)) return true;
  if (stretch(ax, bx, width - 1 - pad, false, u0, u1) && along(Side::Right, ay, by, u0, u1, height - 1)) return true;
  return false;
}

// The side and index ring cell (c, r) is kept under (above), for a cell of the ring (the right
// column's: every other).
inline void ringCellOf(int c, int r, int height, Side& side, int& k) {
  if (r == -1) {
    side = Side::Top, k = c + 1;
  } else if (r == height - 1) {
    side = Side::Bottom, k = c + 1;
  } else if (c == -1) {
    side = Side::Left, k = r + 1;
  } else {
    side = Side::Right, k = r + 1;
  }
}

}  // namespace qota::walk
