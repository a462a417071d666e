// The exact viewshed of a flat grid by a sweep: every pixel's line of sight decided from the
// horizon of the terrain nearer the observer, in time about linear in the pixels.
//
// Why it is exact. Seen from the eye, a line of sight to a pixel is blocked when, somewhere
// strictly between its ends, the terrain is at or above it. Along the line's ground track the
// terrain is linear within each triangle, so the height of the terrain over the line (as an
// angle, w = (z - eye z) / t) is monotone between the points where the track crosses a
// triangle's side; the highest of those crossings decides. In each quadrant round the eye (say
// the one where pixels lie farther east than north or south: 0 < dy / dx = m, |m| <= 1), a
// crossing on a triangle's side projects to (m, w) on one straight segment (the eye's central
// projection maps lines to lines), and the sides of the columns nearer the eye than a pixel
// project to a set of segments whose upper envelope, at the pixel's m, is the highest crossing.
// The sweep goes out column by column, keeping that envelope (a sorted list of pieces, each on
// one side's line); a pixel of the next column reads it at its own m, adds the one or two sides
// its line crosses in its own column, and compares. Columns are far fewer than pixels, and the
// envelope stays short (the horizon).
//
// Voids are holes: across one the terrain may be above a line of sight that meets no triangle.
// So a line that passes over or touches a square with a void corner is visible when it clears
// every crossing, and hidden only by a witness in one piece of terrain: a crossing above it
// before its first void (the eye is above the terrain), or a crossing above it and one below it
// with no void between them (kept per slope for the piece since the last void and for the last
// completed one); else it is left undecided.
//
// What it leaves to an exact test. The envelope is computed in floating point with a bound on
// its error, so pixels whose line passes within that bound of the terrain are left undecided,
// as are the pixels over voids no witness decides and the pixel under the eye. The caller tests
// those exactly, triangle by triangle (viewshed.cpp). The bound covers the rounding here and the
// difference between this grid and the frame's own coordinates (`slack` metres), which the exact
// test uses.
#pragma once

#include <cstdint>
#include <functional>
#include <span>

namespace qota::sweep {

// Heights on a grid: pixel (c, r) at X = c, Y = r, its height z[r * width + c] (metres, voids at
// any finite height and valid 0). The grid is an affine image of the frame's ground plane.
struct Grid {
  int width = 0, height = 0;
  std::span<const double> z;
  std::span<const std::uint8_t> valid;
};

// The eye in grid coordinates (strictly inside the outermost centres' lines: 0 < x < width - 1,
// 0 < y < height - 1), `above` metres over the surface under it (more than 0).
struct Eye {
  double x = 0, y = 0, z = 0, above = 0;
};

enum class Verdict : std::uint8_t { Undecided = 0, Visible = 1, Hidden = 2 };

struct Counts {
  std::size_t decided = 0, undecided = 0;
};

// Verdicts for every valid pixel, written to out (one per pixel, row-major; untouched where the
// pixel has no data). targetHeight: metres over each pixel's surface. slack: metres the frame's
// heights at a point may differ from this grid's through rounding of its coordinates.
// keepGoing(fraction) is asked from time to time on the calling thread; false stops the sweep and
// the call returns false. threads: the parts of the quadrants (slices of their slopes) swept at once.
bool decide(const Grid& grid, const Eye& eye, double targetHeight, double slack, unsigned threads,
            std::span<Verdict> out, Counts& counts, const std::function<bool(double)>& keepGoing);

}  // namespace qota::sweep
