// `voxwall tf list FILE`: the colour maps of a ParaView preset file, for --tf FILE:NAME.
#include <cstdio>
#include <memory>
#include <voxwall/node/transfer_function.hpp>

#include "commands.hpp"

namespace voxwall::cli {

void addTfCommand(CLI::App& app) {
  auto* tf = app.add_subcommand("tf", "Transfer functions: inspect ParaView preset files");
  tf->require_subcommand(1);
  auto file = std::make_shared<std::string>();
  auto* list = tf->add_subcommand(
      "list",
      "List the colour maps of a ParaView preset file, one per line: name, colour space, "
      "points, range ('normalized' when ParaView stretches it over the data), and whether it "
      "has an opacity curve. Pick one with `render --tf FILE:NAME`");
  list->add_option("file", *file, "ParaView preset .json (one preset or a list)")->required();
  list->callback([file] {
    for (const auto& name : node::TransferFunction::namesInParaViewJson(*file)) {
      const auto map = node::TransferFunction::fromParaViewJson(*file, name);
      std::printf("%s\t%s\t%zu points\t%g..%g%s\t%s\n", name.c_str(),
                  node::colorSpaceName(map.colorSpace), map.colors.size(), map.domainMin(),
                  map.domainMax(), map.normalized ? " normalized" : "",
                  map.ownOpacity ? "opacity" : "no opacity");
    }
  });
}

}  // namespace voxwall::cli
