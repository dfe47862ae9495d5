// Coarse-to-fine row order; see row_order.h.
#include "broker/row_order.h"

#include <algorithm>
#include <cassert>

namespace rayfarm {

std::vector<int> coarse_to_fine(int count, int finest_stride) {
  assert(count >= 0 && finest_stride >= 1 && (finest_stride & (finest_stride - 1)) == 0);
  const int grid = (count + finest_stride - 1) / finest_stride;  // multiples of the stride below count
  int bits = 0;
  while ((1 << bits) < grid) ++bits;
  std::vector<int> order;
  order.reserve(static_cast<size_t>(count));
  // Counting in reverse bit order visits 0..2^bits-1; the indices past the grid are skipped.
  for (int i = 0; i < (1 << bits); ++i) {
    int reversed = 0;
    for (int b = 0; b < bits; ++b) reversed |= ((i >> b) & 1) << (bits - 1 - b);
    if (reversed < grid) order.push_back(reversed * finest_stride);
  }
  for (int i = 0; i < count; ++i)
    if (i % finest_stride != 0) order.push_back(i);
  return order;
}

RowCursor::RowCursor(int height) : height_(height), remaining_(height), taken_(static_cast<size_t>(height), 0) {}

RowCursor::BandOrder& RowCursor::order_for(int rows) {
  for (auto& [size, order] : orders_)
    if (size == rows) return order;
  BandOrder order;
  for (int band : coarse_to_fine((height_ + rows - 1) / rows)) order.starts.push_back(band * rows);
  orders_.emplace_back(rows, std::move(order));
  return orders_.back().second;
}

int RowCursor::exclude(int y0, int y1) {
  int freed = 0;
  for (int y = y0; y < y1; ++y) {
    freed += !taken_[static_cast<size_t>(y)];
    taken_[static_cast<size_t>(y)] = 1;
  }
  remaining_ -= freed;
  return freed;
}

std::optional<std::pair<int, int>> RowCursor::take(int rows) {
  assert(rows >= 1);
  if (remaining_ == 0) return std::nullopt;
  BandOrder& order = order_for(rows);
  while (order.next < order.starts.size() && taken_[static_cast<size_t>(order.starts[order.next])]) ++order.next;
  int y0;
  if (order.next < order.starts.size()) {
    y0 = order.starts[order.next++];
  } else {
    // Every band start of this size is taken (by tasks of other sizes): the
    // free rows left are scraps between them; take them from the top.
    while (taken_[static_cast<size_t>(first_free_)]) ++first_free_;
    y0 = first_free_;
  }
  int y1 = y0;
  const int end = std::min(height_, y0 + rows);
  while (y1 < end && !taken_[static_cast<size_t>(y1)]) taken_[static_cast<size_t>(y1++)] = 1;
  remaining_ -= y1 - y0;
  return std::make_pair(y0, y1);
}

}  // namespace rayfarm
