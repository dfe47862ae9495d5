// The image memory rule (tracer/image_memory.h): a frame the holder cannot
// keep is refused before any work, with its size and the limit.
#include <doctest/doctest.h>

#include "tests/run_command.h"
#include "tests/test_files.h"
#include "tests/test_paths.h"
#include "tracer/error.h"
#include "tracer/image_memory.h"

using namespace rayfarm;

TEST_CASE("image memory: 12 bytes a pixel, refused above the limit with both sizes") {
  CHECK(float_image_bytes(65536, 65536) == 51539607552ull);
  CHECK(float_image_bytes(512, 2) == 12288);
  CHECK_NOTHROW(check_image_memory(512, 512, 3u << 20, "the limit"));  // exactly 3 MiB
  CHECK_THROWS_WITH_AS(check_image_memory(512, 513, 3u << 20, "the limit"),
                       "a 512x513 image needs 3.0 MiB as float RGB; the limit is 3.0 MiB", InputError);
  CHECK_THROWS_WITH_AS(check_image_memory(65536, 65536, 8ull << 30, "this machine's memory"),
                       "a 65536x65536 image needs 48.0 GiB as float RGB; this machine's memory is 8.0 GiB",
                       InputError);
  CHECK(physical_memory_bytes() > (64u << 20));
}

TEST_CASE("image memory: render refuses an image this machine cannot hold before it starts") {
  if (physical_memory_bytes() >= float_image_bytes(65536, 65536)) {
    MESSAGE("this machine holds a 65536x65536 float image; nothing to refuse");
    return;
  }
  const std::string render = test::rayfarm_exe() + " render " + test::paper_scene("tetra") + " -o " +
                             (test::scratch_dir("image-memory") / "wide.png").string() +
                             " --width 65536 --height 65536 --spp 1";
  const auto whole = test::run_command(render);
  CHECK(whole.exit_code != 0);
  CHECK(whole.output.find("a 65536x65536 image needs 48.0 GiB as float RGB; this machine's memory is") !=
        std::string::npos);
  // --rows holds only its band.
  const auto one_row = test::run_command(render + " --rows 100:101");
  CHECK_MESSAGE(one_row.exit_code == 0, one_row.output);
}
