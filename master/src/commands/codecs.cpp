#include <cstdio>
#include <memory>
#include <voxwall/codec/registry.hpp>

#include "commands.hpp"

namespace voxwall::cli {
namespace {

std::string joined(const std::vector<std::string>& words) {
  std::string s;
  for (const auto& w : words) s += (s.empty() ? "" : " ") + w;
  return s;
}

void runCodecs(bool list) {
  for (const codec::Codec* c : codec::codecs()) {
    const std::string name(c->name());
    const bool levels = codec::RegisteredCodecs::hasMipLevels(c->id());
    if (list) {  // one line per codec: name, file id, levels or flat, example options
      std::printf("%s\t%u\t%s\t%s\n", name.c_str(), unsigned(c->id()), levels ? "levels" : "flat",
                  joined(c->exampleOptions()).c_str());
      continue;
    }
    std::printf("%s (file id %u%s): %s\n", name.c_str(), unsigned(c->id()),
                levels ? ", mip levels: --lod and --sampling nearest" : "",
                std::string(c->summary()).c_str());
    for (const codec::CodecOption& opt : c->options())
      std::printf("  %-20s%s%s\n", (opt.flag + (opt.isFlag ? "" : " X")).c_str(), opt.help.c_str(),
                  opt.defaultValue.empty() ? "" : (" [" + opt.defaultValue + "]").c_str());
    std::printf("  example: voxwall compress IN -o OUT.vwz --codec %s %s\n", name.c_str(),
                joined(c->exampleOptions()).c_str());
  }
}

}  // namespace

void addCodecsCommand(CLI::App& app) {
  auto list = std::make_shared<bool>(false);
  auto* cmd = app.add_subcommand(
      "codecs", "List the codecs this build carries, their compress options and an example");
  cmd->add_flag(
      "--list", *list,
      "One line per codec, tab-separated: name, file id, 'levels' or 'flat', example options");
  cmd->callback([list] { runCodecs(*list); });
}

}  // namespace voxwall::cli
