// The order in which a frame's rows are handed out: every 8th row first, coarse
// to fine in bit-reversed order (the van der Corput sequence: after 1/32 of the
// rows every 32nd row is done, after 1/16 every 16th, ...), then the other rows
// top to bottom. The first eighth thus covers the whole frame, so a progressive
// preview (status/preview.h) is whole from the start; the rest keeps the old
// top-to-bottom tail, because interleaving every row ends a job on rows spread
// over the frame's dearest middle: in the replay of the paper's lab (balls) that
// cost 18% of the makespan, this order costs nothing (docs/status-page.md).
// Tasks of k rows are bands of k rows in the same order of band index. Pixels
// do not depend on the order (each seeds its own sampler), so neither does the image.
#pragma once

#include <optional>
#include <utility>
#include <vector>

namespace rayfarm {

// A permutation of 0..count-1: the multiples of `finest_stride` (a power of
// two) in bit-reversed order of their index (0, count/2, count/4, 3count/4, ...),
// then the others in increasing order.
std::vector<int> coarse_to_fine(int count, int finest_stride = 8);

// Hands out a frame's rows as contiguous bands [y0, y1) in coarse-to-fine order,
// for tasks of any size, each row once. Pure logic: the broker's TaskBoard and
// the replay's simulator both cut their tasks with it.
class RowCursor {
 public:
  explicit RowCursor(int height);

  // Up to `rows` rows: the first k-row band (k = `rows`) in coarse-to-fine
  // order whose first row is still free, cut short where rows already handed
  // out begin (tasks of another size), or else the topmost free rows.
  // nullopt once every row is handed out.
  std::optional<std::pair<int, int>> take(int rows);

  // Rows [y0, y1) are never to be handed out (e.g. done before a broker
  // restart). Returns how many of them were still free.
  int exclude(int y0, int y1);

  int remaining() const { return remaining_; }
  bool is_free(int y) const { return !taken_[static_cast<size_t>(y)]; }

 private:
  struct BandOrder {
    std::vector<int> starts;  // first rows of the bands, coarse to fine
    size_t next = 0;
  };
  BandOrder& order_for(int rows);

  int height_;
  int remaining_;
  int first_free_ = 0;  // no free row above it
  std::vector<char> taken_;
  std::vector<std::pair<int, BandOrder>> orders_;  // by band size; a job sees one or a few sizes
};

}  // namespace rayfarm
