// Pareto front by pairwise dominance: the study's sweeps have tens of points,
// so O(n^2) is clearer than a sort-and-scan and has no tie-breaking subtleties.
#include "study/pareto.h"

#include <cmath>

namespace rayfarm {

namespace {

bool usable(const CostQuality& p) { return p.cost > 0 && !std::isnan(p.psnr); }

}  // namespace

bool dominates(const CostQuality& a, const CostQuality& b) {
  if (!usable(a) || !usable(b)) return false;
  const bool no_worse = a.cost <= b.cost && a.psnr >= b.psnr;
  return no_worse && (a.cost < b.cost || a.psnr > b.psnr);
}

std::vector<bool> pareto_front(const std::vector<CostQuality>& points) {
  std::vector<bool> on(points.size(), false);
  for (size_t i = 0; i < points.size(); ++i) {
    if (!usable(points[i])) continue;
    bool beaten = false;
    for (size_t j = 0; j < points.size() && !beaten; ++j) beaten = j != i && dominates(points[j], points[i]);
    on[i] = !beaten;
  }
  return on;
}

}  // namespace rayfarm
