// The pixels through which an eye ray can meet the scene. Every primitive
// lies inside the scene's bounding box (Embree's root bounds, which hold
// every primitive's widened box), so an eye ray that misses the box meets
// nothing and brings back the background alone, whatever it would have cost
// to find that out: on tetra, where the object leaves 81% of the image
// empty, 38% of the pixels are ruled out. The box's eight corners,
// projected from the eye onto the image plane, span its image (their
// convex hull); a pixel is ruled out when its square, grown by
// kMarginPixels, lies wholly outside that hull. The margin dwarfs every
// rounding on the way (the float-rounded ray Embree walks differs from the
// sample's direction by under 1e-7 radians, under 1e-4 pixels at 512
// wide). A box wholly behind the eye rules every pixel out; one that
// reaches behind it, or whose corners do not project within a billion
// pixels, rules nothing out.
//
// The scene's box keeps the sky above mount's mountain and tetra's holes;
// the primitives themselves do not. So the footprint is narrowed to the
// union of the primitives' images (add_hull(), keep_only()): each
// primitive lies in the convex hull of a few points (a triangle's corners,
// a sphere's or cone slice's box's), whose image lies in the rectangle
// around the points' images, grown by the same margin. A hull wholly
// behind the eye adds nothing; one that reaches behind it, every pixel.
// Narrowed so, tetra keeps 28% of its pixels instead of 62%, mount 75%
// instead of 98%.
#pragma once

#include <cstdint>
#include <vector>

#include "tracer/camera.h"
#include "tracer/vec3.h"

namespace rayfarm {

class ScreenFootprint {
 public:
  static constexpr double kMarginPixels = 2;
  static constexpr long kHullsBetweenChecks = 256;  // narrow_to_hulls() asks whether to go on this often
  // At most this many bits, 2 MiB: images larger than 4096 x 4096 pixels
  // keep or rule out blocks of 2 x 2 pixels or more at once (a block is
  // kept when one of its pixels is), so that a farm worker rendering a band
  // of a huge image does not hold a bit for each of its pixels.
  static constexpr long long kMaxCells = 1LL << 24;

  // Every pixel of a width x height image: nothing ruled out.
  ScreenFootprint(int width, int height);
  // The pixels through which an eye ray of `camera` may meet the box
  // [lo, hi] (camera-relative, like the rays); an empty box (lo above hi)
  // rules nothing out.
  ScreenFootprint(const CameraModel& camera, int width, int height, const Vec3& lo, const Vec3& hi);
  // No pixel of a width x height image: every one ruled out, until hulls
  // are added.
  static ScreenFootprint none(int width, int height);

  // Rules out every pixel through which no eye ray of `camera` may meet
  // one of the convex hulls that `for_each_hull(visit)` hands `visit`
  // (`bool visit(const Vec3* points, int count)`, false when it asks for no
  // more), every primitive lying in one of them: their union stops growing
  // once it keeps every pixel this keeps (on rings, whose wall fills the
  // image, at the first check).
  template <class ForEachHull>
  void narrow_to_hulls(const CameraModel& camera, ForEachHull&& for_each_hull) {
    ScreenFootprint hulls = none(width_, height_);
    long count = 0;
    for_each_hull([&](const Vec3* points, int n) {
      hulls.add_hull(camera, points, n);
      return ++count % kHullsBetweenChecks != 0 || !hulls.keeps_all_of(*this);
    });
    keep_only(hulls);
  }

  // Keeps the pixels through which an eye ray of `camera` may meet the
  // convex hull of points[0, count) too: those within the margin of the
  // rectangle around the points' images (every pixel when the hull reaches
  // behind the eye, none when it lies wholly behind).
  void add_hull(const CameraModel& camera, const Vec3* points, int count);
  // Rules out every pixel that `other` rules out.
  void keep_only(const ScreenFootprint& other);
  // Whether this keeps every pixel `other` keeps.
  bool keeps_all_of(const ScreenFootprint& other) const;

  // Whether some eye ray through pixel (x, y), anywhere in its square, may
  // meet the scene.
  bool pixel(int x, int y) const {
    const int cx = x >> shift_;
    return (bits_[row_word(y >> shift_) + (cx >> 6)] >> (cx & 63)) & 1;
  }
  // Whether the eye ray through lattice point (i, j) (0 <= i <= width,
  // 0 <= j <= height: the corner the pixels (i - 1 .. i, j - 1 .. j) share)
  // may: whether one of those pixels, inside the image, may.
  bool corner(int i, int j) const { return any(i - 1, i, j - 1, j); }
  // Whether some pixel within `reach` pixels of (x, y), across or down,
  // inside the image, may.
  bool near(int x, int y, int reach) const { return any(x - reach, x + reach, y - reach, y + reach); }
  // How many pixels are ruled out.
  long ruled_out() const;
  // The side, in pixels, of the blocks kept or ruled out at once (1 up to
  // 4096 x 4096 pixels; see kMaxCells).
  int block_side() const { return 1 << shift_; }

 private:
  // Whether some pixel x0 <= x <= x1, y0 <= y <= y1 inside the image may.
  bool any(int x0, int x1, int y0, int y1) const;
  // Keeps pixels x0 <= x <= x1, y0 <= y <= y1, given as doubles that may lie
  // far outside the image (clamped to it here).
  void keep(double x0, double x1, double y0, double y1);
  void keep_cells(int cy, int cx0, int cx1);  // cells cx0 <= cx1 of row cy, inside the image
  void keep_all();
  size_t row_word(int cy) const { return size_t(cy) * words_; }

  int width_, height_;
  int shift_;                    // a cell is 2^shift_ x 2^shift_ pixels (0 up to 4096 x 4096)
  int cells_wide_, cells_high_;
  size_t words_;                 // 64-bit words a row of cells
  std::vector<uint64_t> bits_;   // row by row, bit cx of a row set where cell cx is kept
  bool unbounded_ = false;       // add_hull() met a hull it cannot bound: every pixel kept
};

}  // namespace rayfarm
