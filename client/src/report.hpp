// What the CLI prints: responses as aligned tables, and failed calls with their details.
#pragma once

#include <ostream>

#include <grpcpp/support/status.h>

#include "geotraj/v1/geotraj.pb.h"

namespace geotraj::cli {

void print_table(const v1::ConvertResponse& response, std::ostream& out);
void print_table(const v1::PlanResponse& response, std::ostream& out);
/// A plan's motion summary, optimisation and robot reports (what follows its path tables).
void print_motion_and_reports(const v1::PlanResponse& response, std::ostream& out);
void print_table(const v1::PathProfile& profile, std::ostream& out);
/// What the optimisers did.
void print_table(const v1::OptimizationReport& report, std::ostream& out);
/// The joint-space report of a plan with a robot.
void print_table(const v1::RobotReport& robot, std::ostream& out);
/// The robot models: DH table and limits of each.
void print_table(const v1::ListRobotsResponse& robots, std::ostream& out);

/// Forward kinematics: the tool pose, manipulability, axes and Jacobian.
void print_table(const v1::ForwardKinematicsResponse& fk, std::ostream& out);
/// Inverse kinematics: the solutions nearest the seed first, or the closest pose.
void print_table(const v1::InverseKinematicsResponse& ik, std::ostream& out);

/// Whether the request's samples come in steps (a `step` column in the CSV): a sequence, or a
/// path with the approach move the robot makes to its start (robot.approach).
inline bool has_steps(const v1::PlanRequest& request) {
  return request.sequence_size() > 0 || (request.has_robot() && request.robot().approach() != v1::APPROACH_MOVE_UNSPECIFIED);
}

/// The CSV header of samples like `first` (`geotraj stream`): t,u,s,segment, the tool's pose,
/// velocity, acceleration, speed and angular velocity, `step` when `sequence`, then
/// q0.., qd0.., qdd0.. when the samples carry joints. No newline.
void print_sample_csv_header(const v1::Sample& first, bool sequence, std::ostream& out);
/// One sample as a CSV row under that header (%.17g: exact). No newline.
void print_sample_csv(const v1::Sample& s, bool sequence, std::ostream& out);

/// The status code and message, then each google.rpc.BadRequest field violation of the
/// status details, one per line.
void print_error(const grpc::Status& status, std::ostream& err);

}  // namespace geotraj::cli
