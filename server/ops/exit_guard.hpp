// The exit guard of the server's process (ops/exit_guard.cpp): an exit() that main() did not
// ask for is a failure, whatever status the library that called it chose.
#pragma once

namespace geotraj::server {

/// The exit status of a process that a library ended with exit() (MUMPS's stand-in for
/// MPI_ABORT calls exit(0)): EX_SOFTWARE, so that a supervisor restarts it.
inline constexpr int kAbnormalExitStatus = 70;

/// From now on, an exit() of the process that main() did not allow (allow_exit) ends it
/// with kAbnormalExitStatus instead of the status given: a server that a library stops is
/// a failure, whatever status the library chose. Idempotent.
void guard_exit();
/// main() is about to return (or exit) on purpose: exits keep their status again.
void allow_exit();

}  // namespace geotraj::server
