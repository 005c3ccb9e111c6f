// The CLI's subcommands: read a request, call the service, print the answer.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <google/protobuf/message.h>

#include "connection.hpp"
#include "geotraj/v1/geotraj.pb.h"

namespace geotraj::cli {

/// What `--optimize-*` flags add to a PlanRequest's `optimize` block (over the file's own).
struct OptimizeFlags {
  std::string unspecified;     ///< reading of unspecified constraints (smoothest, thesis-zeros, lowest-degree); empty: the request's
  double max_curvature = 0.0;  ///< path.maxCurvature [1/m]; 0: the request's
  std::string tangent_scales;  ///< objective name (bending-energy, peak-curvature, peak-torsion, arc-length); empty: none
  std::optional<double> length_weight;  ///< optimize.tangentScales.lengthWeight [1/m^2]; absent: the request's
  std::string breakpoints;     ///< objective name (peak-torsion, peak-curvature, peak-derivatives); empty: none
  bool time_optimal = false;   ///< optimize.timing.timeOptimal
  bool jerk_limited = false;   ///< optimize.timing.jerkLimited
  double budget_s = 0.0;       ///< optimize.timeBudgetS when > 0
  /// --optimize-redundancy: criteria and weights, "acceleration=1,range=0.1" (keys range,
  /// velocity, acceleration, jerk, manipulability); empty: none.
  std::string redundancy;
  std::optional<double> velocity_scale;      ///< robot.velocityScale; absent: the request's
  std::optional<double> acceleration_scale;  ///< robot.accelerationScale; absent: the request's
  std::string approach;  ///< robot.approach (joint, linear); empty: the request's
  /// --payload MASS[,X,Y,Z]: robot.payload, kg and its centre of mass [m] in the tool frame;
  /// empty: the request's.
  std::vector<double> payload;
  /// --max-torque JOINT=N_M,...: robot.jointLimits[].maxTorque by joint name; empty: none.
  std::string max_torque;
  /// --joint-limits FILE: MoveIt's joint_limits.yaml as robot.jointLimitsYaml; empty: none.
  std::string joint_limits;
  bool tool_axis_free = false;  ///< robot.toolAxisFree (set when given; false: the request's)
  /// --waypoints: joint waypoints (waypoints.hpp) as the request's jointPath; empty: none.
  std::string waypoints;
  double blend_tolerance = -1.0;  ///< jointPath.blendTolerance [rad or m]; < 0: the request's
  std::string robot;              ///< robot.name; empty: the request's
  std::string urdf;               ///< --urdf FILE: robot.urdf, the file's text; empty: none
  std::string tip_link;           ///< --tip-link LINK: robot.tipLink (with --urdf)
  double rate_hz = 0.0;           ///< motion.cycleRateHz [Hz]; 0: the request's
};

/// What `fk` and `ik` flags write into their requests (over a request file's own).
struct KinematicsFlags {
  std::string robot;                 ///< robot.name; empty: the request's
  std::string urdf;                  ///< --urdf FILE: robot.urdf, the file's text; empty: none
  std::string tip_link;              ///< --tip-link LINK: robot.tipLink (with --urdf)
  std::vector<double> joints;        ///< fk: the joint values [rad or m], joint 0 first
  std::vector<double> seed;          ///< ik: robot.initialJoints
  std::vector<double> position;      ///< ik: target.position (x, y, z) [m]
  std::vector<double> orientation;   ///< ik: target.orientation (w, x, y, z)
  std::optional<std::uint32_t> restarts;
  bool all_solutions = false;
  std::optional<std::uint32_t> max_solutions;
};

/// What the flags of the live subcommands (`execute`, `jog`) write into their first message.
struct LiveFlags {
  std::string script;  ///< --script: timed commands (script.hpp), "-" for stdin; empty: none
  std::optional<double> deadman_s;  ///< options.deadmanS / start.deadmanS [s]; absent: the server's 1 s
  // execute
  std::optional<double> override_percent;  ///< options.speedOverride [%]
  std::optional<double> reserve;           ///< options.accelerationReserve, in [0, 0.9]
  // jog: the robot (exactly one of robot, robot_file, urdf) and JogStart's options
  std::string robot;       ///< a built-in model's name
  std::string robot_file;  ///< a RobotModel in the proto JSON mapping
  std::string urdf;        ///< a URDF file
  std::string tip_link;    ///< --tip-link LINK: robot.tipLink (with --urdf)
  std::vector<double> joints;  ///< robot.initialJoints [rad or m]; empty: the model's home
  std::optional<double> rate_hz;            ///< start.cycleRateHz [Hz]
  std::optional<double> velocity_scale;     ///< start.velocityScale, in (0, 1]
  std::optional<double> max_linear_speed;   ///< start.maxLinearSpeed [m/s]
  std::optional<double> max_angular_speed;  ///< start.maxAngularSpeed [rad/s]
};

/// What `plot` takes beyond the request (plot.cpp).
struct PlotFlags {
  std::string out_dir = ".";  ///< -o: where the figures go (created when missing)
  std::string name;           ///< --name: the files' stem; empty: the request file's stem ("request" for stdin)
  std::string module;         ///< --plot-module (GEOTRAJ_PLOT_MODULE); empty: <exe dir>/../share/geotraj/geotraj_plot.py, then the installed one
  std::string python;         ///< --python (GEOTRAJ_PYTHON); empty: /usr/bin/python3 when present, else python3 on PATH
  std::optional<std::uint32_t> points;  ///< --points: AnalyzePath points per path; absent: the request's, else 2001
  bool png = false;           ///< --png: a PNG beside each SVG
};

struct CallOptions {
  std::string input = "-";  ///< request file in the proto JSON mapping; "-" reads stdin
  bool json = false;        ///< print the response as proto JSON instead of a table
  double timeout_s = 0.0;   ///< deadline of the call [s]; 0: not given
  /// The deadline of a unary call: the one given, else 60 s. A stream has the one given
  /// only (else none: a real-time stream lasts as long as its motion).
  double unary_timeout_s() const { return timeout_s > 0.0 ? timeout_s : 60.0; }
  OptimizeFlags optimize;   ///< applied to PlanRequests
  KinematicsFlags kinematics;  ///< applied to the kinematics requests
  LiveFlags live;              ///< applied to Execute's and Jog's first message
  PlotFlags plot;              ///< `plot`'s own
};

/// Reads `input` ("-": standard input) whole; false when it cannot be read.
bool read_text(const std::string& input, std::string& text);

/// The robot of a request from the CLI's --robot NAME or --urdf FILE (at most one; neither:
/// the request's own): false, with the reason on stderr, where both are given or the file
/// cannot be read.
bool set_robot_source(const std::string& name, const std::string& urdf_file, const std::string& tip_link,
                      v1::RobotSpec& robot);
/// Parses a request file ("-": standard input) in the proto JSON mapping; prints why it
/// cannot (naming the file and the message type) and returns false.
bool read_request(const std::string& input, google::protobuf::Message& request);
/// The `--optimize-*` flags (and the robot's scales and approach) written into the request;
/// false, with a message, for an unknown objective name or a flag the request cannot take.
bool apply_flags(const OptimizeFlags& flags, v1::PlanRequest& request);
/// The PlanRequest of a subcommand: its file read (none given with --waypoints: a request
/// with a motion timed by the limits, durationS 0), then its flags applied (--robot, --rate,
/// --waypoints and --blend-tolerance first). false, with a message, when it cannot be.
bool read_plan_request(const CallOptions& options, v1::PlanRequest& request);

// Each returns the process exit code: 0 on success, 1 when the call failed, 2 when the
// request could not be read.
int run_convert(const Connection& connection, const CallOptions& options);
int run_plan(const Connection& connection, const CallOptions& options);
int run_analyze(const Connection& connection, const CallOptions& options);
/// StreamSamples: one line per sample on stdout, CSV with a header (default) or proto JSON
/// lines (`json`); a progress bar on stderr when stderr is a terminal.
int run_stream(const Connection& connection, const CallOptions& options);
/// Execute: the plan run live, its samples printed as they come (stream's CSV columns plus
/// plan_time, speed_factor and state, or one SampleBatch per line with `json`), a heartbeat
/// every deadman / 4; the keys of a terminal or the --script steer it (live.cpp). 0 when
/// the call ends OK (completed or stopped), 1 otherwise, 2 for a request or script that
/// cannot be read (before the call).
int run_execute(const Connection& connection, const CallOptions& options);
/// Jog: the robot jogged by the --script's commands, its set points printed as they come.
/// Exit codes as run_execute.
int run_jog(const Connection& connection, const CallOptions& options);
/// PlanTrajectory, AnalyzePath of every path and StreamSamples (with a motion), then the
/// plotting module (scripts/geotraj_plot.py, run by Python with matplotlib) draws the figures
/// that apply into options.plot.out_dir and prints one line per file. 0 when every figure
/// was drawn; 1 when a call failed (field violations printed as `plan` prints them), the
/// stream failed (the figures without samples are drawn) or the drawing could not run
/// (python3 or matplotlib missing: the message names Debian's python3-matplotlib); 2 when the
/// request cannot be read or the directory cannot be made.
int run_plot(const Connection& connection, const CallOptions& options);
/// ComputeForwardKinematics: the tool pose, manipulability, axes and Jacobian of the joints
/// given (flags, or a ForwardKinematicsRequest file when options.input is not empty).
int run_fk(const Connection& connection, const CallOptions& options);
/// ComputeInverseKinematics: the joints of a tool pose (every branch with --all), or the
/// closest pose and its distance when out of reach (exit 3 then).
int run_ik(const Connection& connection, const CallOptions& options);
/// ListRobots: the models' DH tables and limits (or the response as proto JSON).
int run_robots(const Connection& connection, const CallOptions& options);
/// Checks grpc.health.v1.Health for `service` ("" is the whole server); 0 when SERVING.
int run_health(const Connection& connection, const std::string& service, double timeout_s);

}  // namespace geotraj::cli
