// Test tool: compares PART.png with the rectangle X,Y,W,H of FULL.png.
//   voxwall_compare_crop FULL X Y W H PART [MIN_PSNR_DB]
// Exit 0 when equal (or at least MIN_PSNR_DB), 1 otherwise, 2 on usage or read errors.
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <voxwall/core/image.hpp>

int main(int argc, char** argv) {
  if (argc != 7 && argc != 8) {
    std::fprintf(stderr, "usage: %s FULL X Y W H PART [MIN_PSNR_DB]\n", argv[0]);
    return 2;
  }
  try {
    const auto full = voxwall::readImage(argv[1]);
    const voxwall::Rect rect{std::atoi(argv[2]), std::atoi(argv[3]), std::atoi(argv[4]),
                             std::atoi(argv[5])};
    const auto part = voxwall::readImage(argv[6]);
    const auto diff = voxwall::compareImages(full.crop(rect), part);
    const double minPsnr = argc == 8 ? std::atof(argv[7]) : 0;
    const bool ok = argc == 8 ? diff.psnrDb >= minPsnr : diff.maxAbs == 0;
    std::printf("%s: max difference %d, PSNR %.2f dB%s\n", argv[6], diff.maxAbs, diff.psnrDb,
                ok ? "" : " -- MISMATCH");
    return ok ? 0 : 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 2;
  }
}
