// voxwall: compress, inspect and render large scalar volumes.
// Errors reach the user as one line, "voxwall: <file>: <what is wrong>", and exit status 1.
#include <cstdio>
#include <exception>
#include <voxwall/core/errors.hpp>
#include <voxwall/core/process.hpp>
#include <voxwall/net/tile_codec.hpp>
#include <voxwall/node/renderer.hpp>

#include "cli_common.hpp"
#include "commands/commands.hpp"

int main(int argc, char** argv) {
  // Large temporary buffers (a volume's slabs while it opens, a frame's bands) go back to the
  // system when freed, instead of staying resident in a worker thread's heap for the whole job.
  voxwall::mapLargeBlocksAlone();
  CLI::App app{
      "voxwall renders large scalar volumes (CT, MRI, microscopy, simulation) from compressed\n"
      "files onto display walls and into image sequences."};
  app.require_subcommand(1);
  app.set_version_flag("--version", "voxwall 0.1.0");
  voxwall::cli::addGenerateCommand(app);
  voxwall::cli::addCompressCommand(app);
  voxwall::cli::addDecompressCommand(app);
  voxwall::cli::addInfoCommand(app);
  voxwall::cli::addCodecsCommand(app);
  voxwall::cli::addRenderCommand(app);
  voxwall::cli::addSinkCommand(app);
  voxwall::cli::addTfCommand(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // Under mpirun every rank parses the same line: only rank 0 explains what is wrong.
    if (voxwall::cli::isNonZeroRank()) return e.get_exit_code();
    return app.exit(e);
  } catch (const voxwall::cli::SilentFailure&) {
    return 1;
  } catch (const voxwall::FormatError& e) {
    std::fprintf(stderr, "voxwall: %s\n", e.what());
    return 1;
  } catch (const voxwall::net::NetError& e) {
    std::fprintf(stderr, "voxwall: %s\n", e.what());
    return 1;
  } catch (const voxwall::node::CudaError& e) {
    std::fprintf(stderr, "voxwall: cuda: %s\n", e.what());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "voxwall: %s\n", e.what());
    return 1;
  }
  return 0;
}
