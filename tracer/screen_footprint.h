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
#pragma once

#include <vector>

#include "tracer/camera.h"
#include "tracer/vec3.h"

namespace rayfarm {

class ScreenFootprint {
 public:
  static constexpr double kMarginPixels = 2;

  // Every pixel of a width x height image: nothing ruled out.
  ScreenFootprint(int width, int height);
  // The pixels through which an eye ray of `camera` may meet the box
  // [lo, hi] (camera-relative, like the rays); an empty box (lo above hi)
  // rules nothing out.
  ScreenFootprint(const CameraModel& camera, int width, int height, const Vec3& lo, const Vec3& hi);

  // Whether some eye ray through pixel (x, y), anywhere in its square, may
  // meet the box.
  bool pixel(int x, int y) const { return x >= rows_[y].begin && x < rows_[y].end; }
  // Whether the eye ray through lattice point (i, j) (0 <= i <= width,
  // 0 <= j <= height: the corner the pixels (i - 1 .. i, j - 1 .. j) share)
  // may: whether one of those pixels, inside the image, may.
  bool corner(int i, int j) const { return any(i - 1, i, j - 1, j); }
  // Whether some pixel within `reach` pixels of (x, y), across or down,
  // inside the image, may.
  bool near(int x, int y, int reach) const { return any(x - reach, x + reach, y - reach, y + reach); }
  // How many pixels are ruled out.
  long ruled_out() const;

 private:
  struct Span {
    int begin, end;  // the pixels [begin, end) of a row that may see the box
  };
  // Whether some pixel x0 <= x <= x1, y0 <= y <= y1 inside the image may.
  bool any(int x0, int x1, int y0, int y1) const;

  std::vector<Span> rows_;
  int width_;
};

}  // namespace rayfarm
