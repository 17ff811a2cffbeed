// Replays a recorded wall frame stream into a running `voxwall sink` as fast as it takes it, with
// light WebSocket clients playing the displays' pages (they answer "ready" as soon as a frame's
// segments arrived and "shown" as soon as they are told to show it, so the measurement is the
// sink's, not a browser's). bench/wall_fps.py starts the sink, runs this and reads the sink's CPU
// time; it prints one line of key=value results.
//
//   voxwall_bench_wall_replay --wall WALL.json --frame FRAME.png --sink HOST:PORT
//       [--http PORT] [--pages N|all] [--ranks R] [--frames F] [--quality Q] [--rate FPS]
//
// The stream is what R ranks send for a frame: the screen in R strips, each rendered in bands of
// 1024 rows, cut into JPEG segments at the display edges the sink's Welcome lists and every 1024
// pixels (q90 4:2:0 by default, as `voxwall render` sends them). Frame ids count up; the bytes are
// the same every frame (encoding is not what is measured).
// First: Boost 1.74's Asio uses std::exchange without including <utility>.
// clang-format off
#include <utility>
// clang-format on
#include <atomic>
#include <barrier>
#include <boost/asio.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/websocket.hpp>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <thread>
#include <vector>
#include <voxwall/core/image.hpp>
#include <voxwall/net/tcp.hpp>
#include <voxwall/net/tile_codec.hpp>
#include <voxwall/walls/wall.hpp>

using namespace voxwall;
namespace beast = boost::beast;
namespace websocket = beast::websocket;
using tcp = boost::asio::ip::tcp;
using Clock = std::chrono::steady_clock;

namespace {

struct Options {
  std::string wall, frame, sink;
  int httpPort = 0, pages = -1, ranks = 2, frames = 300, quality = 90;
  double rate = 0;  // frames per second to send at; 0: as fast as the sink takes them
};

[[noreturn]] void usage(const char* why) {
  std::fprintf(stderr,
               "wall_replay: %s\nusage: voxwall_bench_wall_replay --wall WALL.json --frame "
               "FRAME.png --sink HOST:PORT [--http PORT] [--pages N|all] [--ranks R] [--frames F] "
               "[--quality Q] [--rate FPS]\n",
               why);
  std::exit(2);
}

Options parse(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (i + 1 >= argc) usage(("no value after " + a).c_str());
    const std::string v = argv[++i];
    if (a == "--wall")
      o.wall = v;
    else if (a == "--frame")
      o.frame = v;
    else if (a == "--sink")
      o.sink = v;
    else if (a == "--http")
      o.httpPort = std::atoi(v.c_str());
    else if (a == "--pages")
      o.pages = v == "all" ? -1 : std::atoi(v.c_str());
    else if (a == "--ranks")
      o.ranks = std::atoi(v.c_str());
    else if (a == "--frames")
      o.frames = std::atoi(v.c_str());
    else if (a == "--quality")
      o.quality = std::atoi(v.c_str());
    else if (a == "--rate")
      o.rate = std::atof(v.c_str());
    else
      usage(("unknown option " + a).c_str());
  }
  if (o.wall.empty() || o.frame.empty() || o.sink.empty()) usage("--wall, --frame, --sink");
  if (o.ranks < 1 || o.frames < 1) usage("--ranks and --frames must be positive");
  return o;
}

// A display page that answers at once; counts what it got.
struct FakePage {
  std::string display;
  std::atomic<long long> frames{0}, shows{0}, bytes{0};
  std::atomic<bool> done{false}, connected{false};
  std::thread thread;

  void run(std::uint16_t port) {
    try {
      boost::asio::io_context io;
      websocket::stream<tcp::socket> ws(io);
      ws.next_layer().connect({boost::asio::ip::make_address("127.0.0.1"), port});
      ws.next_layer().set_option(tcp::no_delay(true));  // as browsers do
      ws.handshake("127.0.0.1:" + std::to_string(port), "/ws/display/" + display);
      connected = true;
      beast::flat_buffer in;
      while (!done) {
        ws.read(in);
        const std::string m = beast::buffers_to_string(in.data());
        in.consume(in.size());
        if (ws.got_binary()) {
          std::uint32_t n = 0;
          std::memcpy(&n, m.data(), 4);
          const auto meta = nlohmann::json::parse(m.substr(4, n));
          ++frames;
          bytes += (long long)(m.size() - 4 - n);
          ws.text(true);
          ws.write(boost::asio::buffer("ready " + meta["seq"].dump()));
        } else {
          const auto note = nlohmann::json::parse(m);
          if (note["type"] != "show") continue;
          ++shows;
          const double ms = std::chrono::duration<double, std::milli>(
                                std::chrono::system_clock::now().time_since_epoch())
                                .count();
          char text[96];
          std::snprintf(text, sizeof text, "shown %s %.3f", note["seq"].dump().c_str(), ms);
          ws.text(true);
          ws.write(boost::asio::buffer(std::string(text)));
        }
      }
    } catch (const std::exception& e) {
      if (!done) std::fprintf(stderr, "wall_replay: page %s: %s\n", display.c_str(), e.what());
    }
  }
};

}  // namespace

int main(int argc, char** argv) {
  const Options o = parse(argc, argv);
  try {
    const auto wall = walls::loadWall(o.wall);
    const auto image = voxwall::readImage(o.frame);
    if (image.width != wall.width || image.height != wall.height)
      usage("the frame is not the wall's virtual screen size");
    const auto [host, port] = net::parseEndpoint(o.sink, "--sink");
    const std::uint64_t job = std::random_device{}() | 1;

    // Rank 0's control connection: the sink's word on every frame.
    net::Hello control{net::Role::Controller, 0, o.ranks, wall.id, ""};
    control.jobId = job;
    auto controller = net::Connection::open(host, port, control, 5000);
    std::vector<std::unique_ptr<net::Connection>> ranks;
    for (int r = 0; r < o.ranks; ++r) {
      net::Hello hello{net::Role::Renderer, r, o.ranks, wall.id, ""};
      hello.jobId = job;
      ranks.push_back(net::Connection::open(host, port, hello, 5000));
    }
    const auto cut = ranks[0]->welcome().cut();

    // The recorded stream: every rank's tiles of one frame.
    net::TileCodecSettings codec;
    codec.jpegQuality = o.quality;
    std::vector<std::vector<net::EncodedTile>> tiles(std::size_t(o.ranks));
    long long frameBytes = 0, segments = 0;
    for (int r = 0; r < o.ranks; ++r) {
      const int y0 = wall.height * r / o.ranks, y1 = wall.height * (r + 1) / o.ranks;
      for (int y = y0; y < y1; y += 1024) {
        const voxwall::Rect band{0, y, wall.width, std::min(1024, y1 - y)};
        const auto part = image.crop(band);
        for (auto& t : net::encodeTiles(part, band, wall.background, codec, cut)) {
          frameBytes += (long long)t.bytes.size();
          ++segments;
          tiles[std::size_t(r)].push_back(std::move(t));
        }
      }
    }

    std::vector<std::unique_ptr<FakePage>> pages;
    if (o.httpPort > 0) {
      const int n = o.pages < 0 ? int(wall.displays.size())
                                : std::min<int>(o.pages, int(wall.displays.size()));
      for (int i = 0; i < n; ++i) {
        pages.push_back(std::make_unique<FakePage>());
        pages.back()->display = wall.displays[std::size_t(i)].name;
      }
      for (auto& p : pages)
        p->thread = std::thread([&p, &o] { p->run(std::uint16_t(o.httpPort)); });
      // Every page connected before the clock starts (the first round takes them all in).
      const auto deadline = Clock::now() + std::chrono::seconds(10);
      auto all = [&] {
        for (auto& p : pages)
          if (!p->connected) return false;
        return true;
      };
      while (!all() && Clock::now() < deadline)
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
      if (!all()) throw std::runtime_error("the display pages could not all connect");
    }

    // Replay: each rank's tiles of frame f, then its FrameEnd; the controller's notes counted.
    std::atomic<long long> presented{0}, dropped{0};
    std::atomic<bool> stop{false};
    std::thread notes([&] {
      while (!stop) {
        std::optional<net::Message> m;
        try {
          m = controller->receive(50);
        } catch (const std::exception&) {
          return;  // the sink closed: it has settled every frame it will
        }
        if (!m || m->type != net::MessageType::FrameNote) continue;
        const auto note = net::decodeFrameNote(m->payload, "sink");
        if (note.status == net::FrameStatus::Presented)
          ++presented;
        else
          ++dropped;
      }
    });
    const auto start = Clock::now();
    // The ranks send in parallel and move to the next frame together, as rank 0's frame loop
    // makes them (a frame task for everyone once every report is in).
    std::barrier nextFrame(o.ranks);
    std::atomic<bool> lost{false};
    std::vector<std::thread> senders;
    for (int r = 0; r < o.ranks; ++r)
      senders.emplace_back([&, r] {
        auto& c = *ranks[std::size_t(r)];
        const auto& mine = tiles[std::size_t(r)];
        for (int f = 0; f < o.frames; ++f) {
          if (o.rate > 0)  // the frame's time in a stream of o.rate frames per second
            std::this_thread::sleep_until(start + std::chrono::duration_cast<Clock::duration>(
                                                      std::chrono::duration<double>(f / o.rate)));
          const auto decided = net::unixMicrosNow();
          try {
            if (!lost) {
              for (const auto& t : mine)
                c.send(net::encodeMessage(
                    std::uint64_t(f),
                    net::TileMessage{t.rect, t.codec, decided, t.bytes, 1, 1000}));
              c.send(net::encodeMessage(std::uint64_t(f),
                                        net::FrameEnd{r, std::uint32_t(mine.size())}));
            }
          } catch (const std::exception& e) {
            if (!lost.exchange(true))
              std::fprintf(stderr, "wall_replay: rank %d: %s\n", r, e.what());
          }
          nextFrame.arrive_and_wait();
        }
      });
    for (auto& s : senders) s.join();
    if (lost) return 1;
    // The sink's word on every frame, at most 30 s more.
    const auto waitUntil = Clock::now() + std::chrono::seconds(30);
    while (presented + dropped < o.frames && Clock::now() < waitUntil)
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    const double seconds = std::chrono::duration<double>(Clock::now() - start).count();
    // Let the pages see the last round through.
    if (!pages.empty()) std::this_thread::sleep_for(std::chrono::milliseconds(300));
    stop = true;
    notes.join();
    long long pageFrames = 0, pageShows = 0, pageBytes = 0, minShows = -1;
    for (auto& p : pages) {
      pageFrames += p->frames, pageShows += p->shows, pageBytes += p->bytes;
      minShows = minShows < 0 ? p->shows.load() : std::min(minShows, p->shows.load());
      p->done = true;
    }
    for (auto& r : ranks) r->close();
    controller->close();
    for (auto& p : pages) p->thread.detach();  // blocked in a read; the process ends now
    std::printf(
        "frames=%d presented=%lld dropped=%lld seconds=%.3f presented_per_s=%.2f "
        "frame_bytes=%lld segments=%lld pages=%zu page_frames=%lld page_shows=%lld "
        "min_page_shows=%lld bytes_per_display_frame=%.0f\n",
        o.frames, presented.load(), dropped.load(), seconds, double(presented) / seconds,
        frameBytes, segments, pages.size(), pageFrames, pageShows, std::max(0LL, minShows),
        pageFrames ? double(pageBytes) / double(pageFrames) : 0.0);
    std::fflush(stdout);
    std::_Exit(0);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "wall_replay: %s\n", e.what());
    return 1;
  }
}
