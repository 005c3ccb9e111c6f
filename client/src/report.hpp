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

/// The status code and message, then each google.rpc.BadRequest field violation of the
/// status details, one per line.
void print_error(const grpc::Status& status, std::ostream& err);

}  // namespace geotraj::cli
