// The MPI communicator (Open MPI): point-to-point messages polled against a deadline, so every
// collective has a watchdog. MPI is initialised by the first call and finalised at exit.
#pragma once

#include <voxwall/master/communicator.hpp>

namespace voxwall::master {

// Initialises MPI (thread level FUNNELED) if needed and returns the world communicator.
// Works without mpirun too (a singleton job of one rank). Throws MpiError.
std::unique_ptr<Communicator> makeMpiCommunicator(int* argc, char*** argv);
// Whether this process was started by an MPI launcher (mpirun/mpiexec) with more than one rank,
// judged from the launcher's environment before MPI is initialised.
bool launchedByMpi();

}  // namespace voxwall::master
