// The live calls' wire values (Execute, Jog): their options and commands as core values,
// every violation named by its field, and their samples and status as proto.
#pragma once

#include <cstddef>
#include <optional>
#include <string>

#include "core/error.hpp"
#include "core/live/execution.hpp"
#include "core/live/jog.hpp"
#include "geotraj/v1/geotraj.pb.h"
#include "planner/jog.hpp"
#include "planner/planner.hpp"
#include "server/options.hpp"
#include "server/wire/convert.hpp"

namespace geotraj::server {

/// ExecuteOptions and JogStart defaults.
inline constexpr double kDefaultDeadmanS = 1.0;
inline constexpr double kMaxDeadmanS = 3600.0;
inline constexpr double kDefaultReserve = 0.1;
/// The live calls' cycle rates [Hz]: at least one set point per second.
inline constexpr double kMinLiveRateHz = 1.0;

/// How an Execute call runs, from its first message's `options`.
struct ExecuteSettings {
  double deadman_s = kDefaultDeadmanS;
  double speed_override = 1.0;  ///< fraction in [0, 1] (the wire's percent / 100)
  double reserve = kDefaultReserve;
  std::optional<std::size_t> samples_per_batch;  ///< absent: 10 ms of samples
};

/// ExecuteOptions as settings, or the violations (`options.deadmanS`, ...).
core::Expected<ExecuteSettings> execute_settings(const v1::ExecuteOptions& options);

/// ExecuteRequest.speedOverride [%] as a fraction, or the violation (`speedOverride`).
core::Expected<double> speed_override(double percent);

/// How a Jog call runs, from its first message (`start`): the robot and the jogger's options
/// as given (planner::admit resolves and checks them), the deadman and the batch size.
struct JogSettings {
  planner::JogInput jog;
  double deadman_s = kDefaultDeadmanS;
  std::optional<std::size_t> samples_per_batch;
};

/// JogStart as settings, with the violations of what cannot be read or lies outside its range
/// in `jog.violations` (`start.cycleRateHz`, `start.robot.base.orientation`, ...).
JogSettings jog_settings(const v1::JogStart& start);

/// A later Jog message's command (`joints` or `twist`) for a robot of `dof` joints, or the
/// violations (`joints.velocities[2]`, `twist.linear.x`, `twist.frame`).
core::Expected<core::JogCommand> jog_command(const v1::JogRequest& request, std::size_t dof);

/// Samples per batch of a live call: `given`, or one batch per 10 ms at `rate_hz`.
std::size_t live_batch_size(std::optional<std::size_t> given, double rate_hz);

/// One live set point of Execute (the plan's sample with its plan time and speed factor).
void to_proto(const core::LiveSample& sample, v1::Sample& out);
/// One Jog set point (t, joints, tool pose and twist, damping).
void to_proto(const core::JogSample& sample, v1::Sample& out);
v1::LiveState to_proto(core::LiveState state);

}  // namespace geotraj::server
