// Page decode throughput: how fast one core fills the CPU backend's decoded pages
// (node/page_decode.hpp) from each compressed file, voxel by voxel through the view (the
// reference, and the only way before brick views decoded a page a brick at a time) and the way
// the renderer does now (for zfp and ksvd, through a memo of decoded bricks as large as the
// default --decode-cache gives it, made anew for each pass), in page order and in a shuffled
// order (rays meet pages in no order of the page grid).
//   voxwall_bench_pages [--seconds S] FILE.vwz...
// Every page of the volume is decoded on one thread, in the volume's page format, as often as
// --seconds (default 2) allows per way, at least once; the rate is the volume's voxels over the
// time of one pass over all its pages (each page's apron decoded too), in Mvox/s. Prints a line
// per file:
//   pages FILE codec CODEC voxels N pages P by-voxel R1 no-memo R2 by-page R3
//   shuffled-no-memo R4 shuffled R5
// (no-memo: pages of big bricks without the memo, each thread keeping its last page's bricks, as
// before the memo; for the other codecs the same as with it).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <random>
#include <string>
#include <variant>
#include <vector>
#include <voxwall/codec/registry.hpp>
#include <voxwall/node/page_cache.hpp>
#include <voxwall/node/page_decode.hpp>
#include <voxwall/node/render_volume.hpp>
#include <voxwall/node/renderer.hpp>

using namespace voxwall;

namespace {

double seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

volatile unsigned sink;

struct PageAt {
  int x, y, z;
};

// Every page of `level`, x fastest, or shuffled.
template <class Level>
std::vector<PageAt> pageOrder(const Level& level, bool shuffled) {
  std::vector<PageAt> order;
  for (int pz = 0; pz < node::pages::pagesAlong(level.dimZ); ++pz)
    for (int py = 0; py < node::pages::pagesAlong(level.dimY); ++py)
      for (int px = 0; px < node::pages::pagesAlong(level.dimX); ++px)
        order.push_back({px, py, pz});
  if (shuffled) std::shuffle(order.begin(), order.end(), std::mt19937(1));
  return order;
}

// Passes over the pages in `order`, in `Stored`, with `decodeOne` (after
// `startPass()`) for at least `budget` seconds; the best pass's seconds.
template <class Stored, class Start, class Decode>
double bestPass(const std::vector<PageAt>& order, double budget, Start startPass,
                Decode decodeOne) {
  std::vector<Stored> page(node::pages::kVoxels);
  double best = 1e30, spent = 0;
  do {
    startPass();
    const auto start = std::chrono::steady_clock::now();
    unsigned acc = 0;
    for (const PageAt& p : order) {
      decodeOne(p.x, p.y, p.z, page.data());
      acc += unsigned(page[1000]);
    }
    sink = acc;
    const double s = seconds(start);
    best = std::min(best, s), spent += s;
  } while (spent < budget);
  return best;
}

// The volume's voxels per second (millions) of each way, or false where it has no paged level.
template <class Stored>
bool measure(const node::RenderVolume& v, float bias, double budget, double& byVoxel, double& alone,
             double& byPage, double& aloneShuffled, double& shuffled) {
  bool paged = false;
  const double voxels = double(v.info().voxelCount());
  std::visit(
      [&](const auto& view) {
        using Level = std::remove_cvref_t<decltype(node::pages::pagedLevel(view))>;
        if constexpr (node::PageableLevel<Level>) {
          const Level& level = node::pages::pagedLevel(view);
          paged = true;
          const auto inOrder = pageOrder(level, false), mixed = pageOrder(level, true);
          byVoxel = voxels / 1e6 /
                    bestPass<Stored>(
                        inOrder, budget, [] {},
                        [&](int x, int y, int z, Stored* out) {
                          node::pages::decodePageByVoxel(level, x, y, z, bias, out);
                        });
          // The renderer's way: a fresh memo of bricks each pass, as a PageCache makes it.
          std::unique_ptr<node::pages::BrickMemo> memo;
          const auto fresh = [&] {
            memo.reset();
            memo = node::PageCache::makeMemo(level, v.info().type, node::kDefaultDecodeCacheBytes);
          };
          const auto renderers = [&](int x, int y, int z, Stored* out) {
            node::pages::decodePage(level, x, y, z, bias, out, memo.get());
          };
          byPage = voxels / 1e6 / bestPass<Stored>(inOrder, budget, fresh, renderers);
          shuffled = voxels / 1e6 / bestPass<Stored>(mixed, budget, fresh, renderers);
          alone = byPage, aloneShuffled = shuffled;
          if constexpr (node::pages::sharesBricks<Level>()) {
            const auto before = [&](int x, int y, int z, Stored* out) {
              node::pages::decodePage(level, x, y, z, bias, out);
            };
            alone = voxels / 1e6 /
                    bestPass<Stored>(
                        inOrder, budget, [] {}, before);
            aloneShuffled = voxels / 1e6 /
                            bestPass<Stored>(
                                mixed, budget, [] {}, before);
          }
        }
      },
      v.view());
  return paged;
}

}  // namespace

int main(int argc, char** argv) {
  double budget = 2;
  std::vector<std::string> files;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--seconds" && i + 1 < argc) {
      budget = std::atof(argv[++i]);
    } else if (a.starts_with("-")) {
      std::fprintf(stderr, "usage: %s [--seconds S] FILE.vwz...\n", argv[0]);
      return 2;
    } else {
      files.push_back(a);
    }
  }
  if (files.empty()) {
    std::fprintf(stderr, "usage: %s [--seconds S] FILE.vwz...\n", argv[0]);
    return 2;
  }
  for (const auto& path : files) {
    const auto v = node::RenderVolume::open(path);
    const auto type = v.info().type;
    double byVoxel = 0, alone = 0, byPage = 0, aloneShuffled = 0, shuffled = 0;
    bool paged;
    switch (node::PageCache::formatOf(type)) {
      case node::PageFormat::UInt8:
        paged =
            measure<std::uint8_t>(v, 0.0f, budget, byVoxel, alone, byPage, aloneShuffled, shuffled);
        break;
      case node::PageFormat::UInt16:
        paged = measure<std::uint16_t>(v, type == codec::ScalarType::Int16 ? -32768.0f : 0.0f,
                                       budget, byVoxel, alone, byPage, aloneShuffled, shuffled);
        break;
      default:
        paged = measure<float>(v, 0.0f, budget, byVoxel, alone, byPage, aloneShuffled, shuffled);
        break;
    }
    if (!paged) {
      std::fprintf(stderr, "%s: its codec (%s) has no decoded pages\n", path.c_str(),
                   std::string(codec::codecName(v.info().codec)).c_str());
      return 1;
    }
    const auto& d = v.info().dims;
    const int pageCount = ((d.x + 31) / 32) * ((d.y + 31) / 32) * ((d.z + 31) / 32);
    std::printf(
        "pages %s codec %s voxels %llu pages %d by-voxel %.2f no-memo %.2f by-page %.2f "
        "shuffled-no-memo %.2f shuffled %.2f\n",
        path.c_str(), std::string(codec::codecName(v.info().codec)).c_str(),
        static_cast<unsigned long long>(v.info().voxelCount()), pageCount, byVoxel, alone, byPage,
        aloneShuffled, shuffled);
    std::fflush(stdout);
  }
  return 0;
}
