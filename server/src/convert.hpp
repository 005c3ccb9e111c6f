// The conversion file: proto (geotraj.v1) values <-> core values, and the validation of wire
// input that core cannot see (presence of messages, enum ranges, request-level numbers).
// With status.hpp, the only place where proto and core types meet.
//
// Field paths in violations are complete, in proto JSON names (`path.frames[0].tangent`).
#pragma once

#include <cstddef>
#include <vector>

#include "geotraj/core/analysis.hpp"
#include "geotraj/core/constraints.hpp"
#include "geotraj/core/error.hpp"
#include "geotraj/core/key_frame.hpp"
#include "geotraj/core/motion.hpp"
#include "geotraj/core/orientation.hpp"
#include "geotraj/core/path.hpp"
#include "geotraj/v1/geotraj.pb.h"

namespace geotraj::server {

/// AnalyzePath's point count when PlanRequest.analysis_points is absent, and its limits.
inline constexpr std::size_t kDefaultAnalysisPoints = 101;
inline constexpr std::size_t kMinAnalysisPoints = 2;
inline constexpr std::size_t kMaxAnalysisPoints = 1'000'000;

/// The path of a ConvertRequest as a core PathSpec, or every violation of the request:
/// the wire checks here plus (when those fail) core's validate_path on what could be read,
/// so that one answer lists everything. On success the spec still needs core validation
/// (build_path and convert_path do it); core's field paths are then relative to `path`.
core::Expected<core::PathSpec> path_from_request(const v1::ConvertRequest& request);

/// The same for a PlanRequest; also checks analysis_points and samples_per_batch.
core::Expected<core::PathSpec> path_from_request(const v1::PlanRequest& request);

/// PlanRequest.analysis_points or its default. Precondition: the request passed
/// path_from_request.
std::size_t analysis_points(const v1::PlanRequest& request);

/// Samples per SampleBatch when PlanRequest.samples_per_batch is absent.
inline constexpr std::size_t kDefaultSamplesPerBatch = 256;

/// PlanRequest.motion as a core MotionSpec, or every violation (`motion.rampFraction`, ...):
/// absent optional fields take their documented defaults. Precondition: request.has_motion().
core::Expected<core::MotionSpec> motion_from_request(const v1::PlanRequest& request);

/// PlanRequest.samples_per_batch or its default.
std::size_t samples_per_batch(const v1::PlanRequest& request);

/// PlanTrajectory's motion summary.
void to_proto(const core::MotionPlan& plan, v1::MotionSummary& summary);

/// One streamed sample: the translational sample and the tool orientation at it.
void to_proto(const core::MotionSample& sample, const core::OrientationSample& orientation, v1::Sample& out);

/// ConvertConstraints' answer: the parametric constraints of every frame, per side.
void to_proto(const std::vector<core::FrameConstraints>& frames, v1::ConvertResponse& response);

/// PlanTrajectory's answer (geometry part): segments, arc lengths, the achieved geometry
/// with curvature and torsion derivatives in the path's convention, the closed-loop error.
void to_proto(const core::Path& path, const std::vector<core::AchievedFrame>& achieved,
              const core::ClosedLoopError& closed_loop, v1::PlanResponse& response);

/// AnalyzePath's answer; derivatives per arc length.
void to_proto(const core::Path& path, const std::vector<core::ProfilePoint>& points,
              v1::PathProfile& profile);

}  // namespace geotraj::server
