// geotraj: the command-line client of the geotraj gRPC API.
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <string>

#include <CLI/CLI.hpp>

#include "commands.hpp"
#include "connection.hpp"
#include "planner/robots.hpp"

namespace {

// CLI11's number checks (PositiveNumber, Range) compare, and NaN compares false with
// everything: a floating-point flag is first checked finite (no NaN, no infinity).
const CLI::Validator kFinite(
    [](std::string& text) -> std::string {
      double value = 0.0;
      if (!CLI::detail::lexical_cast(text, value) || !std::isfinite(value)) return "Value " + text + " is not a finite number";
      return {};
    },
    "", "FINITE");

// --tip-link, beside every --urdf.
constexpr const char* kTipLinkHelp =
    "with --urdf: the chain's tip link (robot.tipLink; default: the leaf link through the most moving joints)";

}  // namespace

int main(int argc, char** argv) {
  geotraj::cli::CallOptions options;
  geotraj::cli::ServerAddress server;
  std::string health_service;
  CLI::App app{"geotraj: plan spatial paths through key frames (a gRPC client; without --server it "
               "runs the service in process)."};
  app.require_subcommand(1);
  app.fallthrough();
  app.add_option("--server", server.address, "HOST:PORT of a running geotrajd (plaintext unless --tls)")
      ->envname("GEOTRAJ_SERVER");
  app.add_flag("--tls", server.tls, "connect with TLS, trusting the system's CAs (or --tls-ca)")->envname("GEOTRAJ_TLS");
  app.add_option("--tls-ca", server.ca_file, "CA certificates (PEM) that sign the server's certificate; implies --tls")
      ->envname("GEOTRAJ_TLS_CA");
  app.add_option("--tls-cert", server.cert_file, "client certificate (PEM) for mutual TLS; implies --tls")
      ->envname("GEOTRAJ_TLS_CLIENT_CERT");
  app.add_option("--tls-key", server.key_file, "client private key (PEM) for mutual TLS")->envname("GEOTRAJ_TLS_CLIENT_KEY");
  std::string token_file;
  app.add_option("--token-file", token_file, "file holding a bearer token (its first line), sent on every call")
      ->envname("GEOTRAJ_TOKEN_FILE");
  app.add_option("--timeout", options.timeout_s,
                 "deadline of the call [s]; default: 60 for every call but `stream`, `execute` and `jog`, which have "
                 "none (a motion may last longer than any fixed deadline)")
      ->envname("GEOTRAJ_TIMEOUT")
      ->check(kFinite)->check(CLI::PositiveNumber);
  app.add_flag("--json", options.json, "print the response in the proto JSON mapping instead of a table");
  const auto request_arg = [&](CLI::App* sub, const char* type) {
    sub->add_option("request", options.input, std::string(type) + " in the proto JSON mapping: a file, or - for stdin")
        ->capture_default_str();
  };
  const auto optimize_flags = [&](CLI::App* sub) {
    sub->add_option("--unspecified", options.optimize.unspecified,
                    "what constraints a frame does not give mean: smoothest (the default), thesis-zeros or "
                    "lowest-degree (path.unspecified)");
    sub->add_option("--max-curvature", options.optimize.max_curvature,
                    "warn of bends tighter than this curvature [1/m] (path.maxCurvature)")
        ->check(kFinite)->check(CLI::PositiveNumber);
    sub->add_option("--optimize-tangent-scales", options.optimize.tangent_scales,
                    "optimise the tangent scales: bending-energy, peak-curvature, peak-torsion or arc-length");
    sub->add_option("--length-weight", options.optimize.length_weight,
                    "bending-energy: weight of the arc length [1/m^2]; default E0 / L0 of the request, 0 for the "
                    "energy alone (optimize.tangentScales.lengthWeight)")
        ->check(kFinite)->check(CLI::NonNegativeNumber);
    sub->add_option("--optimize-breakpoints", options.optimize.breakpoints,
                    "optimise the trapezoid breakpoints: peak-torsion, peak-curvature or peak-derivatives");
    sub->add_flag("--time-optimal", options.optimize.time_optimal,
                  "the fastest timing within the robot's joint limits and the Cartesian limits given");
    sub->add_flag("--jerk-limited", options.optimize.jerk_limited, "time-optimal with jerk limits as well (Ipopt)");
    sub->add_option("--optimize-redundancy", options.optimize.redundancy,
                    "choose a redundant arm's self-motion over the whole path: criterion=weight pairs, e.g. "
                    "acceleration=1,range=0.1 (range, velocity, acceleration, jerk, manipulability; "
                    "optimize.redundancy)");
    sub->add_option("--optimize-budget", options.optimize.budget_s, "wall-clock budget of the optimisers [s]")
        ->check(kFinite)->check(CLI::PositiveNumber);
    sub->add_option("--velocity-scale", options.optimize.velocity_scale,
                    "fraction of the robot's joint velocity limits to use, in (0, 1] (robot.velocityScale)");
    sub->add_option("--acceleration-scale", options.optimize.acceleration_scale,
                    "fraction of the robot's joint acceleration and jerk limits to use, in (0, 1] "
                    "(robot.accelerationScale)");
    sub->add_option("--waypoints", options.optimize.waypoints,
                    "joint waypoints as the request's jointPath (without a request file, the request is made of the "
                    "flags): MoveIt's JointTrajectory in JSON ({\"joint_names\": [...], \"points\": [{\"positions\": "
                    "[...]}, ...]}, or a RobotTrajectory's joint_trajectory), a JSON array of arrays, or text with one "
                    "waypoint per line (an optional first line of joint names); joints named are put in a built-in "
                    "robot's order; - for stdin");
    sub->add_option("--blend-tolerance", options.optimize.blend_tolerance,
                    "the joint-space distance at which the joint path may pass an interior waypoint [rad or m] "
                    "(jointPath.blendTolerance); 0: rest at each")
        ->check(kFinite)->check(CLI::NonNegativeNumber);
    sub->add_option("--robot", options.optimize.robot, "a built-in robot's name (robot.name; see `geotraj robots`)");
    sub->add_option("--urdf", options.optimize.urdf,
                    "a URDF file as its maker ships it (robot.urdf; accelerations from --joint-limits or a <geotraj> "
                    "block)");
    sub->add_option("--tip-link", options.optimize.tip_link, kTipLinkHelp);
    sub->add_option("--rate", options.optimize.rate_hz, "the cycle rate [Hz] (motion.cycleRateHz)")
        ->check(kFinite)->check(CLI::PositiveNumber);
    sub->add_option("--approach", options.optimize.approach,
                    "a path that starts away from the robot: joint or linear, a minimum-time move there first "
                    "(robot.approach)")
        ->check(CLI::IsMember({"joint", "linear"}));
    sub->add_option("--payload", options.optimize.payload,
                    "what the tool carries: MASS[,X,Y,Z], kg and its centre of mass in the tool frame [m] "
                    "(robot.payload; a model with mass properties)")
        ->delimiter(',')->expected(1, 4)->check(kFinite);
    sub->add_option("--max-torque", options.optimize.max_torque,
                    "joint torque limits by joint name, JOINT=N_M,... (robot.jointLimits[].maxTorque)");
    sub->add_option("--joint-limits", options.optimize.joint_limits,
                    "MoveIt's joint_limits.yaml: its joints' limits over the model's (robot.jointLimitsYaml)");
    sub->add_flag("--tool-axis-free", options.optimize.tool_axis_free,
                  "the tool is symmetric about its z axis: its roll is chosen with the joints for the whole motion "
                  "(robot.toolAxisFree)");
  };
  auto* convert = app.add_subcommand("convert", "ConvertConstraints: key-frame constraints -> parametric derivatives");
  request_arg(convert, "a ConvertRequest");
  auto* plan = app.add_subcommand("plan", "PlanTrajectory: segments, arc lengths, achieved geometry");
  request_arg(plan, "a PlanRequest");
  optimize_flags(plan);
  auto* analyze = app.add_subcommand("analyze", "AnalyzePath: curvature, torsion and Frenet frames along the path");
  request_arg(analyze, "a PlanRequest");
  optimize_flags(analyze);
  auto* stream = app.add_subcommand("stream", "StreamSamples: the motion sampled at the cycle rate, as CSV (or JSON lines with --json)");
  request_arg(stream, "a PlanRequest with `motion`");
  optimize_flags(stream);
  auto& drawing = options.plot;
  auto* plot = app.add_subcommand(
      "plot", "The request planned, analysed and streamed, its figures drawn with matplotlib (SVG) into a "
              "directory: the path (3-D, top and side views) and its curvature and torsion; the speed with a motion; "
              "the joints against their limits with a robot; which limit binds when time-optimal. Prints the files "
              "written. Needs Python 3 with matplotlib (Debian's python3-matplotlib)");
  request_arg(plot, "a PlanRequest");
  optimize_flags(plot);
  plot->add_option("-o,--out", drawing.out_dir, "directory of the figures (made when missing)")->capture_default_str();
  plot->add_option("--name", drawing.name, "the files' stem (default: the request file's name without .json)");
  plot->add_option("--points", drawing.points,
                   "AnalyzePath points per path (default: the request's analysisPoints, else 2001)")
      ->check(CLI::Range(2, 100001));
  plot->add_flag("--png", drawing.png, "a PNG beside each SVG");
  plot->add_option("--plot-module", drawing.module,
                   "the plotting module geotraj_plot.py (default: <binary's dir>/../share/geotraj/, then the "
                   "installed one)")
      ->envname("GEOTRAJ_PLOT_MODULE");
  plot->add_option("--python", drawing.python,
                   "the Python 3 that draws, with matplotlib (default: /usr/bin/python3, else python3 on PATH)")
      ->envname("GEOTRAJ_PYTHON");
  auto& live = options.live;
  auto* execute = app.add_subcommand(
      "execute", "Execute: the plan run live, its samples printed as they come (stream's CSV plus plan_time, "
                 "speed_factor, state; or one SampleBatch per line with --json). With stdin a terminal and no "
                 "--script, keys steer it: space pause/resume, + and - the speed override by 10 %, s or q stop");
  request_arg(execute, "a PlanRequest with `motion`");
  optimize_flags(execute);
  execute->add_option("--override", live.override_percent, "the speed override at the start [%] (default 100)")
      ->check(kFinite)->check(CLI::Range(0.0, 100.0));
  execute->add_option("--deadman", live.deadman_s,
                      "the deadman time [s] (default 1): the server stops the motion when no message came for this "
                      "long; a heartbeat goes every deadman / 4")
      ->check(kFinite)->check(CLI::PositiveNumber);
  execute->add_option("--acceleration-reserve", live.reserve,
                      "the fraction of the acceleration a time-optimal plan leaves for speed changes (default 0.1)")
      ->check(kFinite)->check(CLI::Range(0.0, 0.9));
  execute->add_option("--script", live.script,
                      "timed commands, one per line: TIME override PCT | pause | resume | stop (TIME [s] from the "
                      "motion's start; # comments); - for stdin");
  auto* jog = app.add_subcommand(
      "jog", "Jog: a robot jogged by a script of joint or Cartesian velocity commands, its set points printed as "
             "they come (t, joints, velocities, tool pose and twist, damping, joints at a limit, state; one "
             "SampleBatch per line with --json)");
  jog->add_option("--robot", live.robot, "a built-in robot's name (see `geotraj robots`)");
  jog->add_option("--robot-file", live.robot_file, "a RobotModel in the proto JSON mapping (- for stdin)");
  jog->add_option("--urdf", live.urdf, "a URDF file as its maker ships it (robot.urdf)");
  jog->add_option("--tip-link", live.tip_link, kTipLinkHelp);
  jog->add_option("--joints", live.joints,
                  "where the robot is: joint values [rad or m], joint 0 first, comma-separated (default: the model's "
                  "home)")
      ->delimiter(',');
  jog->add_option("--rate", live.rate_hz, "set points per second [Hz] (default 100)")->check(kFinite)->check(CLI::PositiveNumber);
  jog->add_option("--velocity-scale", live.velocity_scale,
                  "what a joint command of 1 means, as a fraction of each joint's maximum velocity, in (0, 1] "
                  "(default 0.25)")
      ->check(kFinite)->check(CLI::PositiveNumber);
  jog->add_option("--max-linear-speed", live.max_linear_speed, "the tool's speed at a twist of 1 [m/s] (default 0.25)")
      ->check(kFinite)->check(CLI::PositiveNumber);
  jog->add_option("--max-angular-speed", live.max_angular_speed,
                  "the tool's angular speed at a twist of 1 [rad/s] (default 0.5)")
      ->check(kFinite)->check(CLI::PositiveNumber);
  jog->add_option("--deadman", live.deadman_s, "the deadman time [s] (default 1); a heartbeat goes every deadman / 4")
      ->check(kFinite)->check(CLI::PositiveNumber);
  jog->add_option("--script", live.script,
                  "timed commands, one per line: TIME joints V0 V1 ... | twist world|tool VX VY VZ WX WY WZ | stop "
                  "(each value in [-1, 1]; TIME [s] from the motion's start; # comments); - for stdin")
      ->required();
  auto& kin = options.kinematics;
  auto* fk = app.add_subcommand("fk", "ComputeForwardKinematics: the tool pose, manipulability, axes and Jacobian of "
                                      "joint values");
  fk->add_option("--robot", kin.robot, "a built-in robot's name (see `geotraj robots`)");
  fk->add_option("--urdf", kin.urdf, "or a URDF file as its maker ships it (robot.urdf)");
  fk->add_option("--tip-link", kin.tip_link, kTipLinkHelp);
  fk->add_option("--joints", kin.joints, "joint values [rad or m], joint 0 first, comma-separated")->delimiter(',');
  fk->add_option("--request", options.input, "or a ForwardKinematicsRequest in the proto JSON mapping (- for stdin)");
  auto* ik = app.add_subcommand("ik", "ComputeInverseKinematics: the joints of a tool pose (exit 3 when it is out of "
                                      "reach: the closest pose is printed)");
  ik->add_option("--robot", kin.robot, "a built-in robot's name (see `geotraj robots`)");
  ik->add_option("--urdf", kin.urdf, "or a URDF file as its maker ships it (robot.urdf)");
  ik->add_option("--tip-link", kin.tip_link, kTipLinkHelp);
  ik->add_option("--position", kin.position, "the tool's position x,y,z in W [m]")->delimiter(',');
  ik->add_option("--orientation", kin.orientation, "the tool's orientation as a unit quaternion w,x,y,z (default: "
                                                   "the identity)")
      ->delimiter(',');
  ik->add_option("--seed", kin.seed, "the seed's joint values (default: the robot's home), joint 0 first")
      ->delimiter(',');
  ik->add_option("--restarts", kin.restarts, "attempts after the seed's (default 255; 0: from the seed alone)");
  ik->add_flag("--all", kin.all_solutions, "every distinct solution the attempts find, nearest the seed first");
  ik->add_option("--max-solutions", kin.max_solutions, "the most solutions --all returns (default 16)");
  ik->add_option("--request", options.input, "or an InverseKinematicsRequest in the proto JSON mapping (- for stdin)");
  auto* robots = app.add_subcommand(
      "robots", "ListRobots: the robot models the server knows, joints by name and kind (DH tables, or general "
                "chains read from URDF) with their limits");
  std::string urdf_of;
  robots->add_option("--urdf", urdf_of,
                     "print the URDF document of a built-in model written as URDF (panda, iiwa14, ur5e) and exit: a "
                     "starting point for your own arm's file");
  auto* health = app.add_subcommand("health", "grpc.health.v1 Check: prints the serving status, exit 0 if SERVING");
  health->add_option("--service", health_service, "service name; empty: the whole server");
  app.footer("Environment only: GEOTRAJ_TOKEN, a bearer token sent on every call (secrets do not belong on a "
             "command line).");
  CLI11_PARSE(app, argc, argv);
  if (robots->parsed() && robots->count("--urdf") > 0) {  // no call: the document compiled in
    const std::string_view text = geotraj::planner::builtin_urdf(urdf_of);
    if (text.empty()) {
      std::cerr << "geotraj: robots --urdf: no built-in model \"" << urdf_of
                << "\" written as URDF (panda, iiwa14, ur5e; pa10 and ur5 are DH tables)\n";
      return 2;
    }
    std::cout << text;
    return 0;
  }
  // fk and ik read a request file only when --request names one (their flags suffice).
  for (auto* sub : {fk, ik}) {
    if (sub->parsed() && sub->count("--request") == 0) options.input.clear();
  }
  // A joint path made of --waypoints and the flags needs no request file.
  for (auto* sub : {plan, analyze, stream, plot, execute}) {
    if (sub->parsed() && sub->count("request") == 0 && !options.optimize.waypoints.empty()) options.input.clear();
  }
  if (!token_file.empty()) {
    std::ifstream in(token_file);
    if (!in) {
      std::cerr << "geotraj: --token-file: cannot read \"" << token_file << "\"\n";
      return 2;
    }
    std::getline(in, server.token);
    while (!server.token.empty() && std::isspace(static_cast<unsigned char>(server.token.back()))) server.token.pop_back();
    if (server.token.empty()) {
      std::cerr << "geotraj: --token-file: \"" << token_file << "\" holds no token on its first line\n";
      return 2;
    }
  }
  if (server.token.empty()) {
    if (const char* token = std::getenv("GEOTRAJ_TOKEN")) server.token = token;
  }

  auto connection = geotraj::cli::connect(server);
  if (!connection) {
    std::cerr << "geotraj: " << connection.error() << '\n';
    return 1;
  }
  if (convert->parsed()) return geotraj::cli::run_convert(*connection, options);
  if (plan->parsed()) return geotraj::cli::run_plan(*connection, options);
  if (analyze->parsed()) return geotraj::cli::run_analyze(*connection, options);
  if (stream->parsed()) return geotraj::cli::run_stream(*connection, options);
  if (plot->parsed()) return geotraj::cli::run_plot(*connection, options);
  if (execute->parsed()) return geotraj::cli::run_execute(*connection, options);
  if (jog->parsed()) return geotraj::cli::run_jog(*connection, options);
  if (robots->parsed()) return geotraj::cli::run_robots(*connection, options);
  if (fk->parsed()) return geotraj::cli::run_fk(*connection, options);
  if (ik->parsed()) return geotraj::cli::run_ik(*connection, options);
  return geotraj::cli::run_health(*connection, health_service, options.unary_timeout_s());
}
