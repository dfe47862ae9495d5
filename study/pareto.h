// Pareto fronts of cost against quality: which settings are worth having.
// A point is on the front when no other point costs no more, is no worse, and
// is strictly better in one of the two. The study marks its fronts here and
// writes them into study.csv, so the tables and the plots (which only read the
// CSV) agree on what "on the front" means.
#pragma once

#include <vector>

namespace rayfarm {

// One setting's cost (seconds, or rays traced) and quality (PSNR in dB).
struct CostQuality {
  double cost = 0;
  double psnr = 0;
};

// Whether a dominates b: costs no more, is no worse, and differs in one of them.
bool dominates(const CostQuality& a, const CostQuality& b);

// on_front[i] for each point. Points with a NaN or non-positive cost, or a NaN
// PSNR, are never on the front and dominate nothing. Equal points are both kept.
std::vector<bool> pareto_front(const std::vector<CostQuality>& points);

}  // namespace rayfarm
