// The conversion file: proto (geotraj.v1) values <-> planner and core values, translation
// only. A request is read as given (planner::RequestInput) with the violations of what cannot
// be read (a message core needs that is absent, an enum out of range, a pose that is no
// rotation, key frames core refuses, the server's bounds on sizes); planner::admit judges the
// rest. With status.hpp, the only place where proto and core types meet.
//
// Field paths in violations are complete, in proto JSON names (`path.frames[0].tangent`).
#pragma once

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

#include "core/error.hpp"
#include "core/geometry/analysis.hpp"
#include "core/geometry/constraints.hpp"
#include "core/geometry/geometry_report.hpp"
#include "core/geometry/key_frame.hpp"
#include "core/geometry/path.hpp"
#include "core/motion/motion.hpp"
#include "core/motion/orientation.hpp"
#include "core/planning/joint_motion.hpp"
#include "core/planning/time_optimal.hpp"
#include "core/planning/trajectory.hpp"
#include "core/robot/robot.hpp"
#include "geotraj/v1/geotraj.pb.h"
#include "optim/breakpoints/breakpoints.hpp"
#include "optim/tangent_scales/tangent_scales.hpp"
#include "planner/planner.hpp"
#include "planner/request_input.hpp"
#include "planner/robot_spec.hpp"
#include "planner/robots.hpp"
#include "server/options.hpp"

namespace geotraj::server {

/// AnalyzePath's point count when PlanRequest.analysis_points is absent.
inline constexpr std::size_t kDefaultAnalysisPoints = 101;

/// The path of a ConvertRequest as given (nullopt when it has none): every field read, and
/// what could not be read named from the path; planner::admit_path decides the rest.
std::optional<planner::PathInput> path_input(const v1::ConvertRequest& request, const ServiceLimits& limits);

/// PlanRequest.analysis_points or its default. Precondition: the request was admitted.
std::size_t analysis_points(const v1::PlanRequest& request);

/// Samples per SampleBatch when PlanRequest.samples_per_batch is absent.
inline constexpr std::size_t kDefaultSamplesPerBatch = 256;
/// The most samples in one SampleBatch: about 0.5 MB on the wire with a 7-joint robot
/// (within a gRPC client's default 4 MB receive limit), about 1.3 MB as the message the
/// server fills, so that --max-streams streams at most stay within a few hundred MB.
inline constexpr std::size_t kMaxSamplesPerBatch = 1024;

/// PlanRequest.samples_per_batch or its default.
std::size_t samples_per_batch(const v1::PlanRequest& request);

/// PlanTrajectory's answer: the path's geometry and closed loop (when the plan follows a path),
/// the optimisers' reports (`with_optimization`: the request had `optimize`), the robot's joint
/// report and the motion's summary (duration, samples, the tool's peaks).
void to_proto(const planner::Plan& plan, bool with_optimization, v1::PlanResponse& response);


/// ConvertConstraints' answer: the parametric constraints of every frame, per side.
void to_proto(const std::vector<core::FrameConstraints>& frames, v1::ConvertResponse& response);

/// PlanTrajectory's answer (geometry part): segments, arc lengths, the achieved geometry
/// with curvature and torsion derivatives in the path's convention, the closed-loop error.
void to_proto(const core::Path& path, const std::vector<core::AchievedFrame>& achieved,
              const core::ClosedLoopError& closed_loop, const core::GeometryReport& geometry,
              v1::PlanResponse& response);

/// AnalyzePath's answer; derivatives per arc length.
void to_proto(const core::Path& path, const std::vector<core::ProfilePoint>& points,
              v1::PathProfile& profile);

/// A Pose message as an isometry (an absent orientation is the identity); violations under
/// `field` (`robot.base.position` not finite, `robot.base.orientation` not a unit quaternion).
Eigen::Isometry3d pose_from_proto(const v1::Pose& pose, const std::string& field, core::Violations& out);
/// An isometry as a Pose message.
void to_proto(const Eigen::Isometry3d& X, v1::Pose& out);
void to_proto(const Eigen::Vector3d& v, v1::Vec3& out);

// --- robots ---------------------------------------------------------------------------------

using planner::RobotCatalog;

/// A RobotModel message as a core model, or every violation with field paths under
/// `prefix` (`robot.model.jointType`): enum ranges, orientations that are not unit
/// quaternions, a chain written two ways. Not validated: planner::resolve_robot validates a
/// request's model, robot_model_from_json a file's.
core::Expected<core::RobotModel> robot_model_from_proto(const v1::RobotModel& model, const std::string& prefix);

/// A robot model file: the proto3 JSON form of RobotModel (the form ListRobots returns, and
/// `robot.model` of a request). Errors name the JSON problem or the field.
core::Expected<core::RobotModel> robot_model_from_json(std::string_view json);

/// The full model in its wire form (ListRobots, `geotraj robots`).
void to_proto(const core::RobotModel& model, v1::RobotModel& out);



/// PlanTrajectory's joint-space report.
/// The joint report of a plan on `model` (its name, and where each joint's limits come from).
void to_proto(const core::RobotModel& model, const core::JointMotionReport& report, v1::RobotReport& out);

/// One limit event (also used in error messages).
void to_proto(const core::LimitEvent& event, v1::LimitEvent& out);
/// One stretch of RobotReport.binding or TimingReport.binding.
void to_proto(const core::BindingStretch& stretch, v1::BindingStretch& out);

/// A sentence naming a limit event: kind, joint, sample, time, value and limit.
std::string describe(const core::LimitEvent& event);

/// One streamed sample of any trajectory, with the joints when it has them.
void to_proto(const core::TrajectorySample& sample, v1::Sample& out);

// --- optimisation --------------------------------------------------------------------------

/// Wall-clock budget of all optimisers of one request when OptimizeSpec.timeBudgetS is
/// absent [s] (the RPC's deadline applies as well).
inline constexpr double kDefaultOptimizeBudgetS = 10.0;

/// OptimizeSpec.timeBudgetS or its default (at most `max_seconds`, the server's limit), or
/// the violation (`optimize.timeBudgetS`, also when it asks for more than the limit).
core::Expected<double> optimize_budget(const v1::PlanRequest& request, double max_seconds);

/// The tangent-scale optimiser's options (without deadline), or the violations of
/// `optimize.tangentScales.*` (objective out of range, bounds). Precondition: the request
/// has optimize.tangentScales.
core::Expected<optim::TangentScaleOptions> tangent_scale_options(const v1::PlanRequest& request);

/// The breakpoint optimiser's options (without deadline), or the violations of
/// `optimize.breakpoints.*`. Precondition: the request has optimize.breakpoints.
core::Expected<optim::BreakpointOptions> breakpoint_options(const v1::PlanRequest& request);

// --- the planner's request -------------------------------------------------------------------

/// A PlanRequest as given (planner::RequestInput): every field read into the planner's
/// values, with the violations of what cannot be read (unknown enum values, poses that are
/// not rotations, key frames, the server's `limits` on key frames, analysis points,
/// samples per batch and optimize.timeBudgetS). planner::admit checks the rest.
planner::RequestInput request_input_from_proto(const v1::PlanRequest& request, const ServiceLimits& limits);

/// The optimisers' reports.
void to_proto(const optim::TangentScaleResult& result, v1::TangentScaleReport& out);
void to_proto(const optim::OptimizerReport& report, v1::RedundancyReport& out);
void to_proto(const optim::BreakpointResult& result, v1::BreakpointReport& out);
/// The reports of the optimisers that ran (PlanResponse.optimization).
void to_proto(const planner::OptimizerReports& reports, v1::OptimizationReport& out);
/// The timing optimiser's report with which limit binds where.
void to_proto(const planner::TimingReport& report, v1::TimingReport& out);

}  // namespace geotraj::server
