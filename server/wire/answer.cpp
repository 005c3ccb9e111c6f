// PlanTrajectory's answer and the streamed samples (convert.hpp).
#include <algorithm>
#include <cstdlib>
#include <utility>
#include <variant>

#include "server/wire/convert.hpp"
#include "server/wire/wire_detail.hpp"

namespace geotraj::server {

using namespace wire_detail;

void to_proto(const core::TrajectorySample& sample, v1::Sample& out) {
  out.set_t(sample.t);
  out.set_u(sample.u);
  out.set_s(sample.s);
  out.set_segment(static_cast<std::uint32_t>(sample.segment));
  out.set_step(static_cast<std::uint32_t>(sample.step));
  set(out.mutable_position(), sample.tool.X_WT.translation());
  set(out.mutable_velocity(), sample.tool.v_WT);
  set(out.mutable_acceleration(), sample.tool.a_WT);
  out.set_speed(sample.speed);
  auto* q = out.mutable_orientation();  // wire order (w, x, y, z) by name
  q->set_w(sample.q_WT.w());
  q->set_x(sample.q_WT.x());
  q->set_y(sample.q_WT.y());
  q->set_z(sample.q_WT.z());
  set(out.mutable_angular_velocity(), sample.tool.omega_WT);
  if (!sample.has_joints) return;
  const core::JointSample& joints = sample.joints;
  const auto n = joints.q.size();
  auto* qs = out.mutable_joints();
  auto* qd = out.mutable_joint_velocities();
  auto* qdd = out.mutable_joint_accelerations();
  qs->Reserve(static_cast<int>(n));
  qd->Reserve(static_cast<int>(n));
  qdd->Reserve(static_cast<int>(n));
  for (Eigen::Index i = 0; i < n; ++i) {
    qs->Add(joints.q(i));
    qd->Add(joints.q_dot(i));
    qdd->Add(joints.q_ddot(i));
  }
  if (joints.tau.size() == n) {
    auto* tau = out.mutable_joint_torques();
    tau->Reserve(static_cast<int>(n));
    for (Eigen::Index i = 0; i < n; ++i) tau->Add(joints.tau(i));
  }
}

void to_proto(const planner::OptimizerReports& reports, v1::OptimizationReport& out) {
  if (reports.tangent_scales) to_proto(*reports.tangent_scales, *out.mutable_tangent_scales());
  if (reports.breakpoints) to_proto(*reports.breakpoints, *out.mutable_breakpoints());
  if (reports.timing) to_proto(*reports.timing, *out.mutable_timing());
  if (reports.redundancy) to_proto(*reports.redundancy, *out.mutable_redundancy());
}

void to_proto(const planner::Plan& plan, bool with_optimization, v1::PlanResponse& response) {
  if (plan.path_report) {
    const auto& r = *plan.path_report;
    to_proto(*plan.followed_path(), r.achieved, r.closed_loop, r.geometry, response);
  }
  if (with_optimization) to_proto(plan.optimizers, *response.mutable_optimization());
  if (plan.joints) to_proto(*plan.robot->model, *plan.joints, *response.mutable_robot());
  if (plan.joints && plan.default_jerk) {
    auto& out = *response.mutable_robot()->mutable_default_jerk();
    out.set_ramp_s(plan.default_jerk->ramp_s);
    for (std::size_t i : plan.default_jerk->joints) out.add_joints(static_cast<std::uint32_t>(i));
    for (double j : plan.default_jerk->max_jerk) out.add_max_jerk(j);
    out.set_message(plan.default_jerk->message);
  }
  if (!plan.summary) return;
  const auto set_summary = [](const planner::MotionSummary& from, v1::MotionSummary& out) {
    out.set_duration_s(from.duration_s);
    out.set_sample_count(from.sample_count);
    out.set_peak_speed(from.tool.speed);
    out.set_peak_acceleration(from.tool.acceleration);
    out.set_peak_angular_speed(from.tool.angular_speed);
    out.set_peak_tangential_acceleration(from.peak_tangential_acceleration);
    for (const auto& stretch : from.binding) to_proto(stretch, *out.add_binding());
  };
  set_summary(*plan.summary, *response.mutable_motion());
  const auto* sequence = plan.trajectory ? std::get_if<core::SequenceMotion>(&*plan.trajectory) : nullptr;
  for (std::size_t i = 0; i < plan.steps.size(); ++i) {
    const auto& s = plan.steps[i];
    auto& out = *response.add_steps();
    out.set_index(static_cast<std::uint32_t>(s.index));
    out.set_last_index(static_cast<std::uint32_t>(s.last_index));
    out.set_kind(s.kind);
    out.set_goal_choice(s.goal_choice);
    for (const auto& c : s.corners) {
      auto& corner = *out.add_corners();
      corner.set_after_step(static_cast<std::uint32_t>(s.index + c.after));
      corner.set_segment(static_cast<std::uint32_t>(c.segment));
      corner.set_tolerance(c.tolerance);
      corner.set_deviation(c.deviation);
      corner.set_cut_before(c.cut_before);
      corner.set_cut_after(c.cut_after);
      corner.set_corner(c.corner);
    }
    out.set_start_time_s(s.start_time_s);
    out.set_duration_s(s.duration_s);
    out.set_first_sample(s.first_sample);
    out.set_sample_count(s.sample_count);
    out.set_arc_length(s.arc_length);
    set_summary(planner::MotionSummary{s.duration_s, s.sample_count, s.tool, s.peak_tangential_acceleration, {}},
                *out.mutable_motion());
    const auto* path = sequence != nullptr && s.path ? std::get_if<core::PathMotion>(&sequence->steps[i]) : nullptr;
    if (path != nullptr) {
      v1::PlanResponse one;
      to_proto(path->path, s.path->achieved, s.path->closed_loop, s.path->geometry, one);
      *out.mutable_segments() = std::move(*one.mutable_segments());
      *out.mutable_frames() = std::move(*one.mutable_frames());
      *out.mutable_closed_loop() = std::move(*one.mutable_closed_loop());
      *out.mutable_warnings() = std::move(*one.mutable_warnings());
    }
    // The redundancy optimiser's report even unasked: it runs on every line to goal joints of
    // a redundant arm.
    if ((with_optimization && (s.optimizers.tangent_scales || s.optimizers.breakpoints || s.optimizers.timing)) ||
        s.optimizers.redundancy) {
      to_proto(s.optimizers, *out.mutable_optimization());
    }
  }
}

}  // namespace geotraj::server
