// TCP transport of the wall protocol (Asio): a blocking client connection with deadlines, the
// per-rank tile streamer that reconnects with back-off, and rank 0's control channel.
#pragma once

#include <chrono>
#include <condition_variable>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <voxwall/net/wire.hpp>

namespace voxwall::net {

// "HOST:PORT" -> (host, port). Throws std::invalid_argument naming `option`.
std::pair<std::string, std::uint16_t> parseEndpoint(const std::string& text,
                                                    const std::string& option);

// One connection to the sink. Not thread-safe. Throws NetError ("<host:port>: ...").
class Connection {
 public:
  // Connects, sends Hello and waits for Welcome; a silent sink is a NetError, a Bye (or an answer
  // in another protocol version) a SinkRefused.
  static std::unique_ptr<Connection> open(const std::string& host, std::uint16_t port,
                                          const Hello& hello, int timeoutMs);
  ~Connection();
  // Throws NetError when the bytes are not all sent within timeoutMs (the peer stopped reading).
  void send(std::span<const std::byte> bytes, int timeoutMs = 10000);
  // Waits up to timeoutMs for a whole message; nullopt when none came. Throws NetError when the
  // peer closed or sent garbage.
  std::optional<Message> receive(int timeoutMs);
  const Welcome& welcome() const { return welcome_; }
  const std::string& name() const { return name_; }
  void close();

 private:
  struct Impl;
  explicit Connection(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
  Welcome welcome_;
  std::string name_;
};

// Sends a rank's tiles to the sink, frame by frame. When the sink is unreachable or drops the
// connection, the frame is skipped and the next attempt waits a growing back-off (0.1 s doubling
// to 5 s), so rendering never stalls on a dead sink. A sink that refuses the peer (SinkRefused)
// is not retried: refused() says why and the job should end. While connected, a thread of its
// own sends KeepAlive when nothing was sent for keepAliveMs (0: never), so a rank busy on a long
// frame is not dropped as idle. Not thread-safe (one thread calls it; the keeper is internal).
class TileStreamer {
 public:
  using Clock = std::chrono::steady_clock;
  TileStreamer(std::string host, std::uint16_t port, Hello hello, int connectTimeoutMs = 1000,
               int keepAliveMs = kKeepAliveMs);
  ~TileStreamer();
  TileStreamer(const TileStreamer&) = delete;
  TileStreamer& operator=(const TileStreamer&) = delete;
  // The render job the frames belong to (Hello.jobId); a change reconnects.
  void setJob(std::uint64_t jobId);
  // A frame sent in parts, each as soon as it is rendered: beginFrame, sendTiles per part,
  // endFrame. beginFrame (re)connects if needed, announcing `frame` as the next one in its Hello;
  // it returns false when there is no connection, and then the frame is skipped. A send that
  // fails skips the rest of the frame the same way: later sendTiles and endFrame return false.
  bool beginFrame(std::uint64_t frame);
  // `step` > 1: the tiles are of an interactive frame's reduced screen (wire.hpp), `phase` says
  // why; `renderMicros`: how long this rank has rendered the frame so far (with the last part,
  // its render time for the frame: the sink keeps the value of a rank's last tile).
  bool sendTiles(const std::vector<EncodedTile>& tiles, std::uint64_t decidedUnixMicros,
                 int step = 1, std::uint32_t renderMicros = 0, FramePhase phase = FramePhase::Full);
  // Sends FrameEnd with the count of tiles sent (and whether the job abandoned the frame);
  // returns whether the whole frame went out.
  bool endFrame(bool abandoned = false);
  // Tells the sink that the render job abandoned `frame` (a FrameEnd with the flag and no tiles)
  // when connected and between frames; false when it could not.
  bool abandon(std::uint64_t frame);
  // Where to cut this frame's segments and which to send, as the sink said in its Welcome
  // (valid after a beginFrame that returned true; the default cut otherwise).
  const DisplayCut& displayCut() const { return cut_; }
  // The whole frame at once: beginFrame, sendTiles, endFrame.
  bool sendFrame(std::uint64_t frame, const std::vector<EncodedTile>& tiles,
                 std::uint64_t decidedUnixMicros, int step = 1, std::uint32_t renderMicros = 0);
  // Why the last frame did not go out (empty when it did).
  const std::string& lastError() const { return lastError_; }
  // Why the sink refused this peer for good (empty while it has not).
  const std::string& refused() const { return refused_; }
  std::uint64_t bytesSent() const { return bytesSent_; }
  // Connections this streamer tried to open (refused, failed or made).
  int connectAttempts() const { return connectAttempts_; }
  // The clock the reconnect back-off reads (default: the steady clock): a test advances its own
  // instead of waiting the back-off out. The keeper's KeepAlive interval stays on the real clock.
  void setClock(std::function<Clock::time_point()> clock) { clock_ = std::move(clock); }
  // The screen this job renders and its displays (empty: only the screen is compared): a sink
  // whose Welcome shows another is refused for good, as a sink's own refusal is (a wall file
  // with the sink's wall id but other displays showed nothing and the job exited 0).
  void expectScreen(int width, int height, std::vector<voxwall::Rect> displays);

 private:
  bool ensureConnected();
  // Why the sink's Welcome does not show this job's screen; empty when it does.
  std::string screenMismatch(const Welcome& welcome) const;
  // Sends one whole message (the keeper may send between two); throws NetError when the
  // connection is gone.
  void send(std::span<const std::byte> bytes);
  // A send failed: the connection goes, the frame is skipped, the next attempt waits.
  void lost(const NetError& e);
  void keepAlive();  // the keeper thread's loop
  std::string host_;
  std::uint16_t port_;
  Hello hello_;
  int connectTimeoutMs_;
  std::unique_ptr<Connection> connection_;
  std::chrono::steady_clock::time_point nextAttempt_{};
  std::chrono::milliseconds backoff_{100};
  std::function<Clock::time_point()> clock_ = [] { return Clock::now(); };
  int connectAttempts_ = 0;
  std::string lastError_, refused_;
  DisplayCut cut_;
  int expectWidth_ = 0, expectHeight_ = 0;  // 0: not compared
  std::vector<voxwall::Rect> expectDisplays_;
  std::uint64_t bytesSent_ = 0;
  bool sending_ = false;  // between a beginFrame that connected and endFrame or a failed send
  std::uint64_t frame_ = 0;
  std::uint32_t tilesSent_ = 0;
  // Shared with the keeper thread: the connection, when a message last went out, why the keeper
  // lost the connection.
  std::mutex mutex_;
  std::condition_variable wake_;
  bool stopKeeper_ = false;
  std::chrono::steady_clock::time_point lastSent_{};
  std::string keeperError_;
  int keepAliveMs_;
  std::thread keeper_;
};

// Rank 0's connection for camera and time commands from the wall: a background thread keeps it
// open (reconnecting with back-off), queues every Control and FrameNote that arrives and tells
// the sink where a time series job is (Playback); a sink that refuses the job ends the thread
// and refused() says why. Thread-safe.
class ControlChannel {
 public:
  // While connected it sends KeepAlive every keepAliveMs, and the Playback when it changed.
  ControlChannel(std::string host, std::uint16_t port, Hello hello, int keepAliveMs = kKeepAliveMs);
  ~ControlChannel();
  std::vector<Control> drain();  // the commands received since the last call, in order
  std::size_t pending() const;   // how many drain() would return now
  // What the sink said about frames (dropped or refused ones) since the last call, as lines.
  std::vector<std::string> drainNotes();
  std::string refused() const;            // empty while the sink has not refused the job
  std::uint64_t framesPresented() const;  // frames of this job the sink said it presented
  // Waits up to `wait` until the sink has said something of `frames` frames (presented,
  // dropped, refused, superseded) or presented one; whether it presented any.
  bool waitForPresented(std::uint64_t frames, std::chrono::milliseconds wait);
  // The frame the job renders next: a (re)connection announces it in its Hello.
  void setNextFrame(std::uint64_t frame);
  // Where a time series job is from `frame` on: sent when it differs from the last one sent
  // (and again after a reconnection).
  void setPlayback(std::uint64_t frame, const Playback& playback);

 private:
  void run();
  // One connection's life: sends the playback and keep-alives, queues what the sink says. False
  // when the sink ended the job (refused_ says why); throws when the connection is lost.
  bool serve(Connection& c);
  // Waits `wait`, or less when the channel is stopped; whether it is stopping.
  bool stopsWithin(std::chrono::milliseconds wait);
  std::string host_;
  std::uint16_t port_;
  Hello hello_;
  int keepAliveMs_;
  mutable std::mutex mutex_;
  std::condition_variable wake_;  // told when stop_ is set or a frame note arrives
  std::deque<Control> queue_;
  std::vector<std::string> notes_;
  std::uint64_t presented_ = 0, noted_ = 0;  // notes of presented frames, of any
  std::optional<Playback> playback_;
  std::uint64_t playbackFrame_ = 0, playbackVersion_ = 0;
  std::string refused_;
  bool stop_ = false;
  std::thread thread_;
};

std::uint64_t unixMicrosNow();

}  // namespace voxwall::net
