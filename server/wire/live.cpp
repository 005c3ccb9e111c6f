// The live calls' wire values. See live.hpp.
#include "server/wire/live.hpp"

#include <cmath>

#include "core/format.hpp"
#include "server/wire/convert.hpp"
#include "server/wire/wire_detail.hpp"

namespace geotraj::server {
namespace {

using core::number;

void check_deadman(bool given, double value, const std::string& field, core::Violations& violations) {
  if (given && !(std::isfinite(value) && value > 0.0 && value <= kMaxDeadmanS)) {
    violations.push_back({field, "must be a time in (0, 3600] s, got " + number(value)});
  }
}

void check_batch(bool given, std::uint32_t value, const std::string& field, core::Violations& violations) {
  if (given && (value < 1 || value > kMaxSamplesPerBatch)) {
    violations.push_back({field, "must be in [1, " + std::to_string(kMaxSamplesPerBatch) + "], got " +
                                     std::to_string(value)});
  }
}

void check_fraction(double value, const std::string& field, core::Violations& violations) {
  if (!(std::isfinite(value) && value >= -1.0 && value <= 1.0)) {
    violations.push_back({field, "must be a fraction of the maximum in [-1, 1], got " + number(value)});
  }
}

void set_vec3(v1::Vec3* out, const Eigen::Vector3d& v) {
  out->set_x(v.x());
  out->set_y(v.y());
  out->set_z(v.z());
}

}  // namespace

core::Expected<ExecuteSettings> execute_settings(const v1::ExecuteOptions& options) {
  ExecuteSettings out;
  core::Violations violations;
  check_deadman(options.has_deadman_s(), options.deadman_s(), "options.deadmanS", violations);
  if (options.has_deadman_s()) out.deadman_s = options.deadman_s();
  if (options.has_speed_override()) {
    if (auto fraction = speed_override(options.speed_override())) {
      out.speed_override = *fraction;
    } else {
      violations.push_back({"options.speedOverride", fraction.error().front().description});
    }
  }
  if (options.has_acceleration_reserve()) {
    const double r = options.acceleration_reserve();
    if (!(std::isfinite(r) && r >= 0.0 && r <= 0.9)) {
      violations.push_back({"options.accelerationReserve", "must be a fraction in [0, 0.9], got " + number(r)});
    }
    out.reserve = r;
  }
  check_batch(options.has_samples_per_batch(), options.samples_per_batch(), "options.samplesPerBatch", violations);
  if (options.has_samples_per_batch()) out.samples_per_batch = options.samples_per_batch();
  if (!violations.empty()) return tl::unexpected(std::move(violations));
  return out;
}

core::Expected<double> speed_override(double percent) {
  if (!(std::isfinite(percent) && percent >= 0.0 && percent <= 100.0)) {
    return tl::unexpected(core::Violations{{"speedOverride", "must be a percentage in [0, 100], got " + number(percent)}});
  }
  return percent / 100.0;
}

JogSettings jog_settings(const v1::JogStart& start) {
  JogSettings out;
  core::Violations& violations = out.jog.violations;
  if (start.has_robot()) {
    core::Violations robot;
    out.jog.robot = wire_detail::robot_spec_from_proto(start.robot(), robot);
    for (auto& v : robot) violations.push_back({"start." + v.field, std::move(v.description), v.kind});
  }
  core::JogOptions& o = out.jog.options;
  const auto positive = [&](bool given, double value, double max, const char* field, double& into) {
    if (!given) return;
    if (!(std::isfinite(value) && value > 0.0 && value <= max)) {
      violations.push_back({std::string("start.") + field, "must be in (0, " + number(max) + "], got " + number(value)});
    }
    into = value;
  };
  o.cycle_rate_hz = 100.0;
  o.velocity_scale = 0.25;
  positive(start.has_cycle_rate_hz(), start.cycle_rate_hz(), 10'000.0, "cycleRateHz", o.cycle_rate_hz);
  if (start.has_cycle_rate_hz() && start.cycle_rate_hz() > 0.0 && start.cycle_rate_hz() < kMinLiveRateHz) {
    violations.push_back({"start.cycleRateHz", "must be at least " + number(kMinLiveRateHz) + " Hz, got " +
                                                   number(start.cycle_rate_hz())});
  }
  positive(start.has_velocity_scale(), start.velocity_scale(), 1.0, "velocityScale", o.velocity_scale);
  positive(start.has_max_linear_speed(), start.max_linear_speed(), 10.0, "maxLinearSpeed", o.max_linear_speed);
  positive(start.has_max_angular_speed(), start.max_angular_speed(), 10.0, "maxAngularSpeed", o.max_angular_speed);
  positive(start.has_singular_threshold(), start.singular_threshold(), 10.0, "singularThreshold",
           o.singular_threshold);
  if (start.has_damping()) {
    const double d = start.damping();
    if (!(std::isfinite(d) && d >= 0.0 && d <= 10.0)) {
      violations.push_back({"start.damping", "must be in [0, 10], got " + number(d)});
    }
    o.damping = d;
  }
  check_deadman(start.has_deadman_s(), start.deadman_s(), "start.deadmanS", violations);
  if (start.has_deadman_s()) out.deadman_s = start.deadman_s();
  check_batch(start.has_samples_per_batch(), start.samples_per_batch(), "start.samplesPerBatch", violations);
  if (start.has_samples_per_batch()) out.samples_per_batch = start.samples_per_batch();
  return out;
}

core::Expected<core::JogCommand> jog_command(const v1::JogRequest& request, std::size_t dof) {
  core::Violations violations;
  core::JogCommand out;
  if (request.has_joints()) {
    const auto& v = request.joints().velocities();
    if (static_cast<std::size_t>(v.size()) != dof) {
      violations.push_back({"joints.velocities", "needs one value per joint: " + std::to_string(dof) + ", got " +
                                                     std::to_string(v.size())});
    } else {
      out.joints.resize(static_cast<Eigen::Index>(dof));
      for (int i = 0; i < v.size(); ++i) {
        check_fraction(v[i], "joints.velocities[" + std::to_string(i) + "]", violations);
        out.joints[i] = v[i];
      }
    }
  } else if (request.has_twist()) {
    const auto& t = request.twist();
    core::Vector6d twist;
    const v1::Vec3* parts[2] = {&t.linear(), &t.angular()};
    const char* names[2] = {"twist.linear", "twist.angular"};
    for (int p = 0; p < 2; ++p) {
      const double xyz[3] = {parts[p]->x(), parts[p]->y(), parts[p]->z()};
      const char* axes[3] = {".x", ".y", ".z"};
      for (int k = 0; k < 3; ++k) {
        check_fraction(xyz[k], std::string(names[p]) + axes[k], violations);
        twist[3 * p + k] = xyz[k];
      }
    }
    switch (t.frame()) {
      case v1::COORDINATE_MODE_UNSPECIFIED:
      case v1::COORDINATE_MODE_WORLD: out.frame = core::JogFrame::kWorld; break;
      case v1::COORDINATE_MODE_TOOL: out.frame = core::JogFrame::kTool; break;
      default: violations.push_back({"twist.frame", "must be COORDINATE_MODE_WORLD or COORDINATE_MODE_TOOL, got " +
                                                        std::to_string(static_cast<int>(t.frame()))});
    }
    out.twist = twist;
  } else {
    violations.push_back({"", "expected `joints` or `twist` here"});
  }
  if (!violations.empty()) return tl::unexpected(std::move(violations));
  return out;
}

std::size_t live_batch_size(std::optional<std::size_t> given, double rate_hz) {
  if (given) return *given;
  return static_cast<std::size_t>(std::clamp(std::round(rate_hz * 0.01), 1.0, static_cast<double>(kMaxSamplesPerBatch)));
}

void to_proto(const core::LiveSample& sample, v1::Sample& out) {
  to_proto(sample.sample, out);
  set_vec3(out.mutable_angular_velocity(), sample.sample.tool.omega_WT);
  out.set_plan_time(sample.plan_time);
  out.set_speed_factor(sample.speed_factor);
}

void to_proto(const core::JogSample& sample, v1::Sample& out) {
  out.set_t(sample.t);
  set_vec3(out.mutable_position(), sample.X_WT.translation());
  const Eigen::Quaterniond q(sample.X_WT.linear());
  auto* o = out.mutable_orientation();
  o->set_w(q.w());
  o->set_x(q.x());
  o->set_y(q.y());
  o->set_z(q.z());
  set_vec3(out.mutable_velocity(), sample.twist_W.head<3>());
  set_vec3(out.mutable_angular_velocity(), sample.twist_W.tail<3>());
  out.set_speed(sample.twist_W.head<3>().norm());
  auto* qs = out.mutable_joints();
  auto* qd = out.mutable_joint_velocities();
  auto* qdd = out.mutable_joint_accelerations();
  for (Eigen::Index i = 0; i < sample.q.size(); ++i) {
    qs->Add(sample.q(i));
    qd->Add(sample.q_dot(i));
    qdd->Add(sample.q_ddot(i));
  }
  out.set_damping(sample.damping);
  out.set_smallest_singular_value(sample.sigma_min);
}

v1::LiveState to_proto(core::LiveState state) {
  switch (state) {
    case core::LiveState::kRunning: return v1::LIVE_STATE_RUNNING;
    case core::LiveState::kPausing: return v1::LIVE_STATE_PAUSING;
    case core::LiveState::kPaused: return v1::LIVE_STATE_PAUSED;
    case core::LiveState::kStopping: return v1::LIVE_STATE_STOPPING;
    case core::LiveState::kStopped: return v1::LIVE_STATE_STOPPED;
    case core::LiveState::kCompleted: return v1::LIVE_STATE_COMPLETED;
  }
  return v1::LIVE_STATE_UNSPECIFIED;
}

}  // namespace geotraj::server
