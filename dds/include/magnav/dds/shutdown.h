// Clean stop on SIGINT/SIGTERM: the handler only sets a flag; mains poll it
// (or wait on it) and then delete their DDS entities, so no shared-memory
// segments are left in /dev/shm.
#pragma once

#include <chrono>

namespace magnav::dds {

// Installs handlers for SIGINT and SIGTERM (idempotent).
void InstallShutdownHandlers();
bool ShutdownRequested();
// Requests a stop from inside the program (tests, end of input).
void RequestShutdown();
// Sleeps until a stop is requested or the timeout passes; true if requested.
bool WaitForShutdown(std::chrono::milliseconds timeout);

}  // namespace magnav::dds
