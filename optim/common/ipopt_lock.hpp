// One Ipopt solve at a time in the process.
//
// Debian's Ipopt factors its KKT systems with sequential MUMPS, whose Fortran code keeps its
// state in globals (and whose stand-in MPI ends the process on MPI_ABORT): two solves at once
// on two threads corrupt each other, and the process dies with SIGSEGV or exits. Every use of
// an IpoptApplication in this library, from its creation to its destruction, holds this lock.
// The other solvers (NLopt's Subplex, the banded interior point method) keep their state per
// call and need none.
#pragma once

#include <chrono>
#include <mutex>
#include <stop_token>

namespace geotraj::optim::detail {

/// The process-wide Ipopt lock, taken before `deadline` or before `stop` is requested;
/// an unowned lock (owns_lock() false) when neither left time to take it.
std::unique_lock<std::timed_mutex> lock_ipopt(std::chrono::steady_clock::time_point deadline,
                                              const std::stop_token& stop = {});

}  // namespace geotraj::optim::detail
