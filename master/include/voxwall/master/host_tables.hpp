// Decode tables and value ranges made once a host (codec/host_tables.hpp): the ranks of a job on
// one host agree on one shared file, the one the host's lowest rank made.
#pragma once

#include <string>
#include <voxwall/master/communicator.hpp>

namespace voxwall::master {

// Collective, before any rank opens the volume. Every rank makes a shared file; then every rank
// on a host (same host name and boot id) opens its lowest rank's instead. A rank that cannot (the
// system would not make the file, /proc hides the other process) makes its tables and value
// ranges alone, as a job of one rank does: the pictures are the same. Returns, on rank 0, one line
// for -v: how many ranks share on how many hosts, and which ranks could not and why; empty on
// other ranks.
std::string shareDecodeTablesOnHost(Communicator& comm, int timeoutMs);

}  // namespace voxwall::master
