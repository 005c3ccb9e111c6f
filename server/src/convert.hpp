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
