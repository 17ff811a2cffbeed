// What a codec gives the rest of voxwall: one object per codec, listed in registry.hpp. The
// commands (`compress`, `decompress`, `info`, `codecs`, `render`), RenderVolume, the fuzz target,
// the round-trip tests and the multi-rank scenarios all iterate over the registry; none of them
// names a codec. docs/adding-a-codec.md walks through adding one.
#pragma once

#include <map>
#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <vector>
#include <voxwall/codec/container.hpp>
#include <voxwall/codec/volume.hpp>
#include <voxwall/codec/volume_source.hpp>
#include <voxwall/core/progress.hpp>

namespace voxwall::codec {

class RenderPayload;  // render_payload.hpp
class SeriesSource;   // series_source.hpp

// A command-line option a codec adds to `compress` (e.g. "--quality"). Values arrive as text and
// the codec parses them (CodecOptionValues); an option given with another codec is refused.
struct CodecOption {
  std::string flag;          // "--quality"
  std::string help;          // shown by `compress --help`
  std::string defaultValue;  // shown in the help; empty: none
  bool isFlag = false;       // takes no value
};

// The options given on the command line for the chosen codec, and the options every codec takes.
class CodecOptionValues {
 public:
  int threads = 0;  // encoder threads, 0: every usable core
  // A series: code every step on its own, with no model shared across steps (encodeSeries).
  bool stepsAlone = false;

  void set(const std::string& flag, std::string value) { values_[flag] = std::move(value); }
  bool given(const std::string& flag) const { return values_.count(flag) > 0; }
  // The option's value, or `fallback` when it was not given. The numeric forms throw
  // std::invalid_argument("--flag must be ...") for text that is not a number in [lo, hi].
  std::string text(const std::string& flag, const std::string& fallback) const;
  int integer(const std::string& flag, int fallback, int lo, int hi) const;
  double number(const std::string& flag, double fallback, double lo, double hi) const;
  bool flag(const std::string& flag) const { return given(flag); }
  // The flags given, sorted by name.
  std::vector<std::string> flags() const {
    std::vector<std::string> out;
    for (const auto& [flag, value] : values_) out.push_back(flag);
    return out;
  }

 private:
  std::map<std::string, std::string> values_;
};

// `info` lines: a label (padded to a column) and its text.
using InfoLines = std::vector<std::pair<std::string, std::string>>;

// A small encoded volume for the fuzzer's seed corpus and the tests that run every codec.
struct CodecSample {
  std::string name;  // file-name friendly: "vq-lossy"
  CompressedVolume volume;
};

// The view types a codec's payloads produce (a codec class's `Views`).
template <class... Views>
struct ViewList {};

class Codec {
 public:
  virtual ~Codec() = default;
  // The id files of this codec store and its name on the command line: the codec's registry
  // entry's `kId` and `kName`.
  virtual CodecId id() const = 0;
  virtual std::string_view name() const = 0;
  // One sentence for `compress --help` and `voxwall codecs`: what it does, which data it takes.
  virtual std::string_view summary() const = 0;
  virtual std::vector<CodecOption> options() const { return {}; }
  // False for a codec that stores the voxels as they are (raw, bricked with an apron): `compress`
  // holds every other codec's sections to the voxels' size (largerThanVoxels below).
  virtual bool compresses() const { return true; }
  // Encodes `volume`. `report` receives what `compress` prints under its summary line: lines
  // that each start with "\n  ". Throws std::invalid_argument for options or data it refuses.
  virtual CompressedVolume encode(const Volume& volume, const CodecOptionValues& options,
                                  Progress& progress, std::string& report) const = 0;
  // Encodes the volume `source` reads, holding a bounded window of its slices at a time where the
  // codec streams (then the file equals encode()'s of the whole volume, byte for byte). By
  // default: the whole volume in memory, then encode().
  virtual CompressedVolume encodeSource(const VolumeSource& source,
                                        const CodecOptionValues& options, Progress& progress,
                                        std::string& report) const;
  // Encodes a time series, one step after the other (step k of `series.open(k)`), holding one
  // step's input at a time. By default every step is encoded on its own (encodeSource) and
  // makeSeries stores the sections all steps have alike once; a codec whose model can serve
  // every step (a dictionary, a codebook) overrides it to train one model on all steps.
  // `report` receives step 0's report and the codec's words on the series.
  virtual CompressedSeries encodeSeries(const SeriesSource& series,
                                        const CodecOptionValues& options, Progress& progress,
                                        std::string& report) const;
  // The full volume. Throws FormatError for sections that do not describe one.
  virtual Volume decode(const VolumeInfo& info, const SectionSet& sections) const = 0;
  // The codec's `info` lines (after the container's).
  virtual InfoLines describe(const VolumeInfo& info, const SectionSet& sections) const = 0;
  // Validates the sections and makes them ready to render (views, value ranges). Throws
  // FormatError, also for a file this codec holds but cannot render. The sections must outlive
  // the payload.
  virtual std::unique_ptr<RenderPayload> open(const VolumeInfo& info,
                                              const SectionSet& sections) const = 0;
  // The `render` flags this codec owns (e.g. tvq's "--progressive"): `render` registers them,
  // refuses them for another codec's file and hands the given ones to open() below.
  virtual std::vector<CodecOption> renderOptions() const { return {}; }
  // open() with the render flags given (only this codec's renderOptions()); by default the
  // codec has none and ignores them. Throws std::invalid_argument for a bad value.
  virtual std::unique_ptr<RenderPayload> openWith(const VolumeInfo& info,
                                                  const SectionSet& sections,
                                                  const CodecOptionValues& renderOptions) const;
  // Reads and checks everything a reader can be handed (the fuzz target calls it on untrusted
  // bytes): by default decode(). Throws FormatError.
  virtual void verify(const VolumeInfo& info, const SectionSet& sections) const {
    (void)decode(info, sections);
  }
  // Small encoded volumes of every kind the codec writes (lossless, lossy, each layout).
  virtual std::vector<CodecSample> samples() const = 0;
  // `compress` options that make a lossy (or otherwise typical) file of this codec from a small
  // volume, for `voxwall codecs` and the multi-rank scenarios.
  virtual std::vector<std::string> exampleOptions() const = 0;
};

// What every codec writes alike, from its registry entry `Entry` (kId, kName): its id and name.
template <class Entry>
class CodecOf : public Codec {
 public:
  CodecId id() const final { return Entry::kId; }
  std::string_view name() const final { return Entry::kName; }
};

// A codec that streams (it overrides encodeSource): encode() of a volume in memory is
// encodeSource() of it, so that both give the same file byte for byte.
template <class Entry>
class StreamingCodecOf : public CodecOf<Entry> {
 public:
  CompressedVolume encode(const Volume& volume, const CodecOptionValues& options,
                          Progress& progress, std::string& report) const final {
    return this->encodeSource(*memorySource(volume), options, progress, report);
  }
};

// `count` fresh ids for the caches of decoded bricks and pages, unique in the process whatever
// the codec: a layout takes its ids when it is opened, so a cache never serves one layout's
// bricks for another's.
std::uint64_t mintCacheIds(std::uint64_t count = 1);

// Whether `compressed` is larger than the voxels it codes: its sections hold more bytes than the
// voxels at their scalar type, beyond an allowance of 4 KiB plus 1/256 for the codec's parameters
// and indices (the container's header and table come on top of either).
bool largerThanVoxels(const CompressedVolume& compressed);
// The same for a series: every section against the voxels of every step.
bool largerThanVoxels(const CompressedSeries& compressed);

// Every codec this build carries, in id order.
const std::vector<const Codec*>& codecs();
// The codec with this id; null when this build does not carry it.
const Codec* findCodec(CodecId id);
// The codec with this name; throws std::invalid_argument naming the ones there are.
const Codec& codecNamed(std::string_view name);
// The codec of a container's volume; throws FormatError("<source>: unknown codec id N ...") when
// this build does not carry it.
const Codec& codecOf(const VolumeInfo& info, const std::string& source);
// The name of the codec with this id, or "id N" when this build does not carry it.
std::string codecName(CodecId id);
// "raw, vq, svmm"
std::string codecNames();
// The codecs whose `list` (Codec::options for compress, Codec::renderOptions for render) has
// `flag`: "vq" or "ksvd or tvq".
std::string codecsTaking(const std::string& flag, std::vector<CodecOption> (Codec::*list)() const);

}  // namespace voxwall::codec
