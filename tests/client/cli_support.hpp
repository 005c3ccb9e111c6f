// Running the geotraj CLI as a user does, from the client tests: one shell command, its
// output captured and its exit status.
#pragma once

#include <sys/wait.h>

#include <cstdio>
#include <string>

namespace geotraj::testing {

struct CliRun {
  int exit_code = -1;
  std::string out;  ///< what the command wrote to its standard output (and stderr when redirected there)
};

/// Runs `command` through the shell (popen) and captures its standard output.
inline CliRun run_shell(const std::string& command) {
  CliRun run;
  FILE* pipe = ::popen(command.c_str(), "r");
  if (pipe == nullptr) return run;
  char buf[4096];
  std::size_t n = 0;
  while ((n = std::fread(buf, 1, sizeof buf, pipe)) > 0) run.out.append(buf, n);
  const int status = ::pclose(pipe);
  run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return run;
}

}  // namespace geotraj::testing
