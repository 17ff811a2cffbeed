// Frame-codec benchmark: how fast voxwall compresses a whole wall frame into tiles, per core,
// and how many bytes a frame takes, for JPEG (the wall default), deflate and raw RGB. Writes the
// frame as a PPM so libjpeg-turbo's own tjbench can run on the same pixels (bench/wall_bench.sh).
//   voxwall_bench_tiles FRAME.png OUT.ppm [QUALITY] [SUBSAMPLING] [SECONDS] [SEGMENT_PIXELS]
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>
#include <voxwall/core/parallel.hpp>
#include <voxwall/net/tile_codec.hpp>

using namespace voxwall;

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr,
                 "usage: %s FRAME.png OUT.ppm [QUALITY] [444|422|420] [SECONDS] [SEGMENT]\n",
                 argv[0]);
    return 2;
  }
  const auto image = voxwall::readImage(argv[1]);
  const int quality = argc > 3 ? std::atoi(argv[3]) : 90;
  const std::string sub = argc > 4 ? argv[4] : "420";
  const double seconds = argc > 5 ? std::atof(argv[5]) : 3.0;
  const int segmentPixels = argc > 6 ? std::atoi(argv[6]) : net::TileCodecSettings{}.segmentPixels;
  {
    std::ofstream ppm(argv[2], std::ios::binary);
    ppm << "P6\n" << image.width << " " << image.height << "\n255\n";
    for (auto p : image.pixels) {
      const char rgb[3] = {char(p & 255), char((p >> 8) & 255), char((p >> 16) & 255)};
      ppm.write(rgb, 3);
    }
  }
  const double megapixels = double(image.width) * image.height / 1e6;
  std::printf("frame %dx%d (%.1f MP), raw RGB %.1f MB\n", image.width, image.height, megapixels,
              megapixels * 3);
  std::printf("| codec | threads | MP/s | MP/s per core | bytes/frame | bits/pixel |\n");
  std::printf("|---|---|---|---|---|---|\n");
  const int cores = voxwall::usableCores();
  for (auto codecKind : {net::TileCodec::Jpeg, net::TileCodec::Deflate}) {
    for (int threads : {1, cores}) {
      if (threads == cores && cores == 1 && codecKind != net::TileCodec::Jpeg) continue;
      net::TileCodecSettings s;
      s.codec = codecKind;
      s.jpegQuality = quality;
      s.subsampling = sub == "444"   ? net::Subsampling::S444
                      : sub == "422" ? net::Subsampling::S422
                                     : net::Subsampling::S420;
      s.threads = threads;
      s.segmentPixels = segmentPixels;
      std::size_t bytes = 0;
      int frames = 0;
      const auto start = std::chrono::steady_clock::now();
      double elapsed = 0;
      do {
        const auto tiles = net::encodeTiles(image, {0, 0, image.width, image.height}, {0, 0, 0}, s);
        bytes = 0;
        for (const auto& t : tiles) bytes += t.bytes.size();
        ++frames;
        elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      } while (elapsed < seconds);
      const double rate = megapixels * frames / elapsed;
      const std::string label = codecKind == net::TileCodec::Jpeg
                                    ? "jpeg q" + std::to_string(quality) + " " + sub
                                    : std::string("deflate level 1 (exact)");
      std::printf("| %s | %d | %.1f | %.1f | %.2f MB | %.2f |\n", label.c_str(), threads, rate,
                  rate / threads, double(bytes) / 1e6, double(bytes) * 8 / (megapixels * 1e6));
      if (codecKind == net::TileCodec::Deflate) break;  // one row is enough for the exact mode
    }
  }
  return 0;
}
