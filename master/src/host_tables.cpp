// Which shared file of decode tables each rank of a job uses (host_tables.hpp).
#include <fstream>
#include <map>
#include <sstream>
#include <voxwall/codec/host_tables.hpp>
#include <voxwall/master/host_tables.hpp>

namespace voxwall::master {

namespace {

// What names a host: its name and the kernel's boot id (two machines may share a name, and
// containers on one kernel may differ in name but then /proc tells them apart anyway).
std::string hostKey(const Communicator& comm) {
  std::ifstream in("/proc/sys/kernel/random/boot_id");
  std::string boot;
  std::getline(in, boot);
  return comm.hostName() + "/" + (boot.empty() ? "-" : boot);
}

struct Offer {
  std::string host;
  bool made = false;  // the rank made a file
  codec::hosttables::Peer peer;
};

Offer parse(const std::string& line) {
  std::istringstream in(line);
  Offer o;
  long long pid = 0;
  unsigned long long inode = 0;
  in >> o.host >> o.made >> pid >> o.peer.fd >> inode;
  o.peer.pid = pid, o.peer.inode = inode;
  return o;
}

}  // namespace

std::string shareDecodeTablesOnHost(Communicator& comm, int timeoutMs) {
  Offer mine;
  mine.host = hostKey(comm);
  std::string problem;
  try {
    mine.peer = codec::hosttables::create();
    mine.made = true;
  } catch (const std::exception& e) {
    problem = e.what();
  }
  std::ostringstream text;
  text << mine.host << ' ' << mine.made << ' ' << mine.peer.pid << ' ' << mine.peer.fd << ' '
       << mine.peer.inode;
  std::string all;
  for (const auto& line : gatherStrings(comm, text.str(), timeoutMs)) all += line + '\n';
  all = broadcastString(comm, all, timeoutMs);
  std::istringstream lines(all);
  std::vector<Offer> offers;
  for (std::string line; std::getline(lines, line);) offers.push_back(parse(line));
  if (problem.empty()) {
    for (int r = 0; r < int(offers.size()); ++r) {
      const Offer& o = offers[std::size_t(r)];
      if (o.host != mine.host || !o.made) continue;
      if (r != comm.rank()) problem = codec::hosttables::join(o.peer);
      break;  // the lowest rank on this host with a file; this rank's own if it is that rank
    }
  }
  // Rank 0 learns who shares and who could not.
  const auto verdicts = gatherStrings(comm, problem, timeoutMs);
  if (comm.rank() != 0) return {};
  std::map<std::string, int> perHost;
  std::string failures;
  for (std::size_t r = 0; r < verdicts.size() && r < offers.size(); ++r) {
    if (verdicts[r].empty())
      ++perHost[offers[r].host];
    else
      failures += "; rank " + std::to_string(r) + " makes its own: " + verdicts[r];
  }
  int sharing = 0;
  for (const auto& [host, n] : perHost) sharing += n;
  return "value ranges and decode tables made once a host: " + std::to_string(sharing) +
         " rank(s) on " + std::to_string(perHost.size()) + " host(s) share them" + failures;
}

}  // namespace voxwall::master
