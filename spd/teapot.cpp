// teapot: the Newell teapot's 32 Bezier patches, each evaluated on a size x size
// grid and split into triangles with vertex normals (NFF `pp`), standing on a
// size x size checkerboard; 2 lights. Must be rendered two-sided. Triangles
// that collapse at the lid and bottom cusps are dropped: 64 n^2 - 8 n patches.

#include <cmath>

#include "spd/generators.h"
#include "spd/teapot_data.h"

namespace rayfarm::spd {
namespace {

// Bicubic Bezier basis for row vectors: p(s, t) = S * M * G * M^T * T^T with
// S = (s^3, s^2, s, 1) (Foley & van Dam, ch. 11).
Matrix bezier_basis() {
  Matrix ms;
  const double m[4][4] = {
      {-1.0, 3.0, -3.0, 1.0}, {3.0, -6.0, 3.0, 0.0}, {-3.0, 3.0, 0.0, 0.0}, {1.0, 0.0, 0.0, 0.0}};
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) ms.m[r][c] = m[r][c];
  return ms;
}

Matrix transpose(const Matrix& a) {
  Matrix t;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) t.m[c][r] = a.m[r][c];
  return t;
}

double dot4(const Coord& a, const Coord& b) {
  return a.x * b.x + a.y * b.y + a.z * b.z + a.w * b.w;
}

// Power vector (u^3, u^2, u, 1) and its derivative (3u^2, 2u, 1, 0), built by
// repeated multiplication as the original does.
void power_vectors(double u, Coord& p, Coord& dp) {
  double v[4], dv[4];
  double val = 1.0, dval = 1.0;
  for (int k = 3; k >= 0; --k) {
    v[k] = val;
    val *= u;
    if (k == 3) {
      dv[k] = 0.0;
      dval = 1.0;
    } else {
      dv[k] = dval * double(3 - k);
      dval *= u;
    }
  }
  p = {v[0], v[1], v[2], v[3]};
  dp = {dv[0], dv[1], dv[2], dv[3]};
}

// Point and unit normal (t tangent x s tangent) of the patch whose per-axis
// M G M^T matrices are `mgm`.
void evaluate(const Matrix (&mgm)[3], double s, double t, Coord& point, Coord& normal) {
  Coord sp, dsp, tp, dtp;
  power_vectors(s, sp, dsp);
  power_vectors(t, tp, dtp);
  double p[3], sdir[3], tdir[3];
  for (int i = 0; i < 3; ++i) {
    const Coord a = transform_coord(sp, mgm[i]);
    p[i] = dot4(a, tp);
    sdir[i] = dot4(transform_coord(dsp, mgm[i]), tp);
    tdir[i] = dot4(a, dtp);
  }
  point = {p[0], p[1], p[2], 0.0};
  normal = cross({tdir[0], tdir[1], tdir[2], 0.0}, {sdir[0], sdir[1], sdir[2], 0.0});
  normalize(normal);
}

// The lid knob and the bottom centre are cusps where the normal vanishes. A
// triangle with two vertices there is degenerate (dropped: returns false); one
// with a single cusp vertex gets the axis direction as that vertex's normal.
bool fix_cusp(const Coord (&v)[3], Coord (&n)[3]) {
  int count = 0, cusp = 0;
  for (int i = 2; i >= 0; --i) {
    if (std::fabs(v[i].x) <= 0.0001 && std::fabs(v[i].y) <= 0.0001) {
      ++count;
      cusp = i;
    }
  }
  if (count > 1) return false;
  if (count == 1) n[cusp] = {0.0, 0.0, v[cusp].z > 1.5 ? 1.0 : -1.0, 0.0};
  return true;
}

void write_patch(int patch, int size, const Matrix& ms, const Matrix& mst, NffWriter& out) {
  Matrix mgm[3];
  for (int axis = 0; axis < 3; ++axis) {
    Matrix g;
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c)
        g.m[r][c] = teapot_data::kVertices[teapot_data::kPatches[patch][r * 4 + c]][axis];
    mgm[axis] = multiply(multiply(ms, g), mst);
  }
  for (int si = 0; si < size; ++si) {
    for (int ti = 0; ti < size; ++ti) {
      // Grid cell corners 0..3 = (s,t), (s+1,t), (s+1,t+1), (s,t+1); the two
      // triangles are corners (0,1,2) and (2,3,0).
      for (int tri = 0; tri < 2; ++tri) {
        Coord v[3], n[3];
        for (int k = 0; k < 3; ++k) {
          const int corner = (k + tri * 2) % 4;
          const double s = double(si + (corner / 2 ? 1 : 0)) / double(size);
          const double t = double(ti + (corner % 3 ? 1 : 0)) / double(size);
          evaluate(mgm, s, t, v[k], n[k]);
        }
        if (fix_cusp(v, n)) out.patch(v, n, 3);
      }
    }
  }
}

// Square (si, ti) of the board spanning [-4, 4]^2 at z = 0.
void write_square(int si, int ti, int size, NffWriter& out) {
  Coord v[4];
  for (int i = 0; i < 4; ++i) {
    v[i].x = 4.0 * (2.0 * double(si + (i % 3 ? 1 : 0)) / double(size) - 1.0);
    v[i].y = 4.0 * (2.0 * double(ti + (i / 2 ? 1 : 0)) / double(size) - 1.0);
    v[i].z = 0.0;
  }
  out.polygon(v, 4);
}

void write_checkerboard(int size, NffWriter& out) {
  for (int parity = 1; parity >= 0; --parity) {  // white squares first, then grey
    const double grey = parity ? 1.0 : 0.5;
    out.surface({grey, grey, grey, /*kd*/ 0.5, /*ks*/ 0.5, /*phong*/ 30.0, /*kt*/ 0.0,
                 /*ior*/ 0.0});
    for (int si = 0; si < size; ++si)
      for (int ti = 0; ti < size; ++ti)
        if ((si + ti) % 2 == parity) write_square(si, ti, size, out);
  }
}

}  // namespace

void write_teapot(int size, NffWriter& out) {
  write_sky_and_view(out, {4.86, 7.2, 5.4}, {0.0, 0.0, 0.0}, {0.0, 0.0, 1.0}, 1.0);
  out.light({-3.1, 9.8, 12.1});
  out.light({11.3, 5.1, 8.8});
  write_checkerboard(size, out);

  out.surface({1.0, 0.5, 0.1, /*kd*/ 0.75, /*ks*/ 0.25, /*phong*/ 37.0, /*kt*/ 0.0, /*ior*/ 0.0});
  const Matrix ms = bezier_basis();
  const Matrix mst = transpose(ms);
  for (int patch = 0; patch < teapot_data::kPatchCount; ++patch)
    write_patch(patch, size, ms, mst, out);
}

}  // namespace rayfarm::spd
