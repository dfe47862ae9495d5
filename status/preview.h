// Progressive preview: the image of a frame while it renders. Rows not done yet
// show the pixels of the nearest done row (the upper one on a tie), so with rows
// handed out coarse to fine (broker/row_order.h) the preview at 10% of a job is
// already the whole frame at a coarser vertical resolution. Pixels become 8-bit
// exactly as in the final PNG (to_8bit), so a complete preview is the final image.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace rayfarm {

// For each row, the done row whose pixels it shows: itself when done, else the
// nearest done row; -1 for every row when none is done.
std::vector<int> preview_source_rows(const std::vector<bool>& done);

// How far (in rows) the farthest row is from the done row it shows; the height
// when no row is done. 0 means the preview is the final image.
int preview_fill_distance(const std::vector<bool>& done);

// The preview as 8-bit RGB (width * height * 3): `rgb` holds the frame's float
// RGB, meaningful in the rows `done` marks. With no row done, the frame is black.
std::vector<uint8_t> preview_rgb8(int width, int height, const std::vector<float>& rgb,
                                  const std::vector<bool>& done);

// The same, as a PNG stream.
std::string preview_png(int width, int height, const std::vector<float>& rgb, const std::vector<bool>& done);

}  // namespace rayfarm
