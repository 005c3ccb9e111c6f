// The scripts of the live subcommands (`execute --script`, `jog --script`): one timed command
// per line, read and checked whole before the call.
//
//   # a comment (a line or the rest of one)
//   TIME COMMAND [ARGS...]
//
// TIME [s] is the motion's own time (Sample.t: 0 at its first sample), >= 0 and never less
// than the line before's. A command is sent once a sample at or after its TIME has arrived.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include <tl/expected.hpp>

namespace geotraj::cli {

/// One line of an execute script: `TIME override PCT`, `TIME pause`, `TIME resume`, `TIME stop`.
struct ExecuteStep {
  enum class Kind { kOverride, kPause, kResume, kStop };
  double t_s = 0.0;      ///< motion time [s]
  Kind kind = Kind::kStop;
  double percent = 0.0;  ///< kOverride: the speed override [%], in [0, 100]
  int line = 0;          ///< 1-based line number in the script
};

/// One line of a jog script: `TIME joints v0 v1 ...`, `TIME twist world|tool vx vy vz wx wy wz`,
/// `TIME stop`.
struct JogStep {
  enum class Kind { kJoints, kTwist, kStop };
  double t_s = 0.0;  ///< motion time [s]
  Kind kind = Kind::kStop;
  /// kJoints: one fraction of each joint's maximum velocity in [-1, 1], joint 0 first;
  /// kTwist: (vx, vy, vz, wx, wy, wz), fractions of the maximum linear and angular speed.
  std::vector<double> values;
  bool tool_frame = false;  ///< kTwist: in the tool frame T (else the world frame W)
  int line = 0;
};

/// Every problem of a script, one message per bad line, each naming the script and the line
/// ("script run.txt, line 3: unknown command \"fast\" ...: `1.0 fast`").
using ScriptErrors = std::vector<std::string>;

/// `text` read as an execute script named `name` (for the messages). Lines after a `stop` are
/// an error (the call ends there).
tl::expected<std::vector<ExecuteStep>, ScriptErrors> parse_execute_script(std::string_view text,
                                                                          const std::string& name);

/// `text` read as a jog script named `name`: every `joints` line has the same number of
/// values; lines after a `stop` are an error. A script without a `stop` is returned as it is
/// (the caller stops after its last line).
tl::expected<std::vector<JogStep>, ScriptErrors> parse_jog_script(std::string_view text, const std::string& name);

}  // namespace geotraj::cli
