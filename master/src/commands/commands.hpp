// Each subcommand registers itself on the top-level app.
#pragma once

#include <CLI/CLI.hpp>

namespace voxwall::cli {

void addGenerateCommand(CLI::App& app);
void addCompressCommand(CLI::App& app);
void addDecompressCommand(CLI::App& app);
void addInfoCommand(CLI::App& app);
void addCodecsCommand(CLI::App& app);
void addRenderCommand(CLI::App& app);
void addSinkCommand(CLI::App& app);
void addTfCommand(CLI::App& app);

}  // namespace voxwall::cli
