// The conversion file (see convert.hpp): proto <-> core values and the wire checks.
#include "server/wire/convert.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <memory>
#include <set>
#include <sstream>
#include <string>
#include <type_traits>
#include <utility>
#include <variant>

#include "core/geometry/validate.hpp"
#include "core/robot/kinematics.hpp"
#include "planner/robot_spec.hpp"
#include "planner/robots.hpp"
#include "core/format.hpp"

#include <google/protobuf/util/json_util.h>

namespace geotraj::server {
namespace {

using Eigen::Vector3d;

// --- small value conversions -------------------------------------------------------------

Vector3d to_core(const v1::Vec3& v) { return {v.x(), v.y(), v.z()}; }

void set(v1::Vec3* out, const Vector3d& v) {
  out->set_x(v.x());
  out->set_y(v.y());
  out->set_z(v.z());
}


std::string at_frame(std::size_t i) { return "path.frames[" + std::to_string(i) + "]"; }

// --- wire checks ----------------------------------------------------------------------------

// The wire checks of one request, with the fields whose core checks would only repeat them.
struct WireCheck {
  core::Violations violations;
  std::set<std::string> suppressed;  ///< core field paths (relative to `path`) to drop

  void add(std::string field, std::string description) {
    violations.push_back({std::move(field), std::move(description)});
  }
};

// Records a violation when `value` is not a value of the enum (proto3 enums are open:
// unknown numbers survive parsing), naming the values that are.
void check_enum(WireCheck& check, const std::string& field, int value,
                const google::protobuf::EnumDescriptor* descriptor) {
  if (descriptor->FindValueByNumber(value) != nullptr) return;
  std::string names;
  for (int i = 0; i < descriptor->value_count(); ++i) {
    if (!names.empty()) names += ", ";
    names += descriptor->value(i)->name();
  }
  check.add(field, "unknown value " + std::to_string(value) + "; use one of " + names);
}

// A quaternion whose norm is within this of 1 is accepted as a rotation.
constexpr double kUnitQuaternionTolerance = 1e-3;

void check_frame(WireCheck& check, const v1::KeyFrame& frame, std::size_t i) {
  const std::string at = at_frame(i);
  const std::string core_at = "frames[" + std::to_string(i) + "]";
  if (!frame.has_position()) check.add(at + ".position", "is required: the position of the key frame in metres");
  if (!frame.has_tangent()) {
    check.add(at + ".tangent", "is required: the unit tangent of the path at the key frame");
    // Without a tangent, core's checks of the normal and binormal against it are noise.
    check.suppressed.insert(core_at + ".normal");
    check.suppressed.insert(core_at + ".binormal");
  }
  check_enum(check, at + ".orientationMode", frame.orientation_mode(), v1::OrientationMode_descriptor());
  const bool custom = frame.orientation_mode() == v1::ORIENTATION_MODE_CUSTOM;
  if (custom && !frame.has_orientation()) {
    check.add(at + ".orientation",
              "is required with orientationMode ORIENTATION_MODE_CUSTOM: the tool orientation to turn to");
  }
  if (!custom && frame.has_orientation() && v1::OrientationMode_IsValid(frame.orientation_mode())) {
    check.add(at + ".orientation", "is only used with orientationMode ORIENTATION_MODE_CUSTOM; orientationMode is " +
                                       v1::OrientationMode_Name(frame.orientation_mode()));
  }
  if (frame.ease_orientation() && frame.orientation_mode() != v1::ORIENTATION_MODE_CUSTOM &&
      frame.orientation_mode() != v1::ORIENTATION_MODE_FRAME_BASED &&
      v1::OrientationMode_IsValid(frame.orientation_mode())) {
    check.add(at + ".easeOrientation", "eases a SLERP: it needs orientationMode ORIENTATION_MODE_CUSTOM or "
                                       "ORIENTATION_MODE_FRAME_BASED; orientationMode is " +
                                           v1::OrientationMode_Name(frame.orientation_mode()));
  }
  if (frame.has_orientation()) {
    const auto& q = frame.orientation();
    const double norm = std::sqrt(q.w() * q.w() + q.x() * q.x() + q.y() * q.y() + q.z() * q.z());
    if (!std::isfinite(norm) || std::abs(norm - 1.0) > kUnitQuaternionTolerance) {
      check.add(at + ".orientation", "must be a unit quaternion (norm within " + core::number(kUnitQuaternionTolerance, 6) +
                                         " of 1), got (w, x, y, z) = (" + core::number(q.w(), 6) + ", " + core::number(q.x(), 6) + ", " +
                                         core::number(q.y(), 6) + ", " + core::number(q.z(), 6) + ") of norm " + core::number(norm, 6));
    }
  }
}

void check_path(WireCheck& check, const v1::PathSpec& path) {
  for (int i = 0; i < path.frames_size(); ++i) check_frame(check, path.frames(i), static_cast<std::size_t>(i));
  check_enum(check, "path.derivativeConvention", path.derivative_convention(),
             v1::DerivativeConvention_descriptor());
  check_enum(check, "path.blend", path.blend(), v1::BlendMethod_descriptor());
  check_enum(check, "path.unspecified", path.unspecified(), v1::UnspecifiedConstraints_descriptor());
}

// --- proto -> core --------------------------------------------------------------------------

core::KeyFrame to_core(const v1::KeyFrame& f) {
  core::KeyFrame k;
  k.p_W = to_core(f.position());
  if (f.has_tangent()) k.T_W = to_core(f.tangent());
  if (f.has_normal()) k.N_W = to_core(f.normal());
  if (f.has_binormal()) k.B_W = to_core(f.binormal());
  if (f.has_curvature()) k.kappa = f.curvature();
  if (f.has_curvature_derivative()) k.kappa_d = f.curvature_derivative();
  if (f.has_torsion()) k.tau = f.torsion();
  if (f.has_torsion_derivative()) k.tau_d = f.torsion_derivative();
  if (f.has_tangent_scale()) k.tangent_scale = f.tangent_scale();
  if (f.has_leave_tangent_scale()) k.leave_tangent_scale = f.leave_tangent_scale();
  k.ease_orientation = f.ease_orientation();
  k.cusp = f.cusp();
  k.inflection = f.inflection();
  k.stop = f.stop();
  switch (f.orientation_mode()) {
    case v1::ORIENTATION_MODE_FRAME_BASED: k.orientation_mode = core::OrientationMode::kFrameBased; break;
    case v1::ORIENTATION_MODE_CUSTOM: k.orientation_mode = core::OrientationMode::kCustom; break;
    case v1::ORIENTATION_MODE_FRENET: k.orientation_mode = core::OrientationMode::kFrenet; break;
    case v1::ORIENTATION_MODE_PARALLEL_TRANSPORT: k.orientation_mode = core::OrientationMode::kParallelTransport; break;
    default: k.orientation_mode = core::OrientationMode::kFixed; break;  // FIXED and UNSPECIFIED
  }
  if (f.has_orientation()) {
    // Wire order (w, x, y, z) by name; Eigen stores (x, y, z, w).
    const auto& q = f.orientation();
    k.orientation = Eigen::Quaterniond(q.w(), q.x(), q.y(), q.z()).normalized();
  }
  return k;
}

core::PathSpec to_core(const v1::PathSpec& p) {
  core::PathSpec spec;
  spec.frames.reserve(static_cast<std::size_t>(p.frames_size()));
  for (const auto& f : p.frames()) spec.frames.push_back(to_core(f));
  spec.convention = p.derivative_convention() == v1::DERIVATIVE_CONVENTION_PER_PARAMETER
                        ? core::DerivativeConvention::kPerParameter
                        : core::DerivativeConvention::kPerArcLength;
  spec.blend = p.blend() == v1::BLEND_METHOD_TRAPEZOIDAL ? core::BlendMethod::kTrapezoidal
                                                         : core::BlendMethod::kPolynomial;
  for (const auto& b : p.breakpoints()) {
    core::SegmentBreakpoints s;
    s.segment = b.segment();
    s.all.assign(b.all().begin(), b.all().end());
    s.x.assign(b.x().begin(), b.x().end());
    s.y.assign(b.y().begin(), b.y().end());
    s.z.assign(b.z().begin(), b.z().end());
    spec.breakpoints.push_back(std::move(s));
  }
  spec.closed = p.closed();
  if (p.has_max_curvature()) spec.max_curvature = p.max_curvature();
  switch (p.unspecified()) {
    case v1::UNSPECIFIED_CONSTRAINTS_THESIS_ZEROS: spec.unspecified = core::UnspecifiedConstraints::kThesisZeros; break;
    case v1::UNSPECIFIED_CONSTRAINTS_LOWEST_DEGREE: spec.unspecified = core::UnspecifiedConstraints::kLowestDegree; break;
    default: spec.unspecified = core::UnspecifiedConstraints::kSmoothest; break;  // SMOOTHEST and UNSPECIFIED
  }
  return spec;
}

// N for a field path under `path.frames[N]`, -1 for the path's other fields.
long frame_index(const std::string& field) {
  static const std::string prefix = "path.frames[";
  if (field.rfind(prefix, 0) != 0) return -1;
  return std::strtol(field.c_str() + prefix.size(), nullptr, 10);
}

// The path of a request after every wire check: the path's own, then `request_checks` on
// the request's other fields. When any fails, core's validation of what could be read
// joins them (after the path's wire checks, before the request's), so that one answer
// lists everything.
template <class RequestChecks>
core::Expected<core::PathSpec> read_path(bool has_path, const v1::PathSpec& path, int max_frames,
                                         RequestChecks request_checks) {
  // A path longer than the server accepts is refused before any of it is read.
  if (has_path && path.frames_size() > max_frames) {
    return tl::unexpected(core::Violations{
        {"path.frames", "has " + std::to_string(path.frames_size()) + " key frames; this server accepts at most " +
                            std::to_string(max_frames) + " (geotrajd --max-frames)"}});
  }
  WireCheck check;
  if (has_path) {
    check_path(check, path);
  } else {
    check.add("path", "is required: the key frames of the path (at least 2)");
  }
  WireCheck request_level;
  request_checks(request_level);
  if (check.violations.empty() && request_level.violations.empty()) return to_core(path);
  if (has_path) {
    auto validated = core::validate_path(to_core(path));
    if (!validated) {
      for (auto& v : validated.error()) {
        if (check.suppressed.count(v.field) == 0) check.add("path." + v.field, std::move(v.description));
      }
    }
  }
  // The path's violations in frame order (the wire checks and core's interleaved).
  std::stable_sort(check.violations.begin(), check.violations.end(),
                   [](const auto& a, const auto& b) { return frame_index(a.field) < frame_index(b.field); });
  for (auto& v : request_level.violations) check.violations.push_back(std::move(v));
  return tl::unexpected(std::move(check.violations));
}

// --- core -> proto --------------------------------------------------------------------------

void to_proto(const core::SideConstraints& side, v1::SideConstraints* out) {
  for (int k = 0; k < side.order; ++k) set(out->add_derivatives(), side.d[static_cast<std::size_t>(k)]);
  set(out->mutable_tangent(), side.T);
  if (!side.N.isZero()) {
    set(out->mutable_normal(), side.N);
    set(out->mutable_binormal(), side.T.cross(side.N));
  }
}

// The Frenet apparatus, each quantity only where it is defined; derivatives per arc length
// or per unit u.
template <class Out>
void set_geometry(const core::LocalGeometry& g, bool per_arc_length, Out* out) {
  if (!g.regular) return;
  set(out->mutable_tangent(), g.T);
  out->set_curvature(g.kappa);
  if (!g.has_normal) return;
  set(out->mutable_normal(), g.N);
  set(out->mutable_binormal(), g.B);
  out->set_torsion(g.tau);
  out->set_curvature_derivative(per_arc_length ? g.kappa_ds : g.kappa_du);
  out->set_torsion_derivative(per_arc_length ? g.tau_ds : g.tau_du);
}

void to_proto(const core::LocalGeometry& g, bool per_arc_length, v1::FrenetGeometry* out) {
  out->set_speed(g.speed);
  set_geometry(g, per_arc_length, out);
}

v1::BlendMethod to_proto(core::BlendMethod b) {
  return b == core::BlendMethod::kTrapezoidal ? v1::BLEND_METHOD_TRAPEZOIDAL : v1::BLEND_METHOD_POLYNOMIAL;
}

}  // namespace

core::Expected<core::PathSpec> path_from_request(const v1::ConvertRequest& request, const ServiceLimits& limits) {
  return read_path(request.has_path(), request.path(), limits.max_frames, [](WireCheck&) {});
}

core::Expected<core::PathSpec> path_from_request(const v1::PlanRequest& request, const ServiceLimits& limits) {
  return read_path(request.has_path(), request.path(), limits.max_frames, [&request, &limits](WireCheck& check) {
    if (request.has_analysis_points() &&
        (request.analysis_points() < 2 || request.analysis_points() > limits.max_analysis_points)) {
      check.add("analysisPoints", "must be between 2 (both ends of the path) and " +
                                      std::to_string(limits.max_analysis_points) +
                                      " (geotrajd --max-analysis-points), got " +
                                      std::to_string(request.analysis_points()));
    }
    if (request.has_samples_per_batch() &&
        (request.samples_per_batch() == 0 || request.samples_per_batch() > kMaxSamplesPerBatch)) {
      check.add("samplesPerBatch", "must be between 1 and " + std::to_string(kMaxSamplesPerBatch) + " when given, got " +
                                       std::to_string(request.samples_per_batch()));
    }
  });
}

core::Expected<core::MotionSpec> motion_from_request(const v1::PlanRequest& request) {
  const auto& m = request.motion();
  WireCheck check;
  check_enum(check, "motion.profile", m.profile(), v1::MotionProfile_descriptor());
  check_enum(check, "motion.timeParameterization", m.time_parameterization(), v1::TimeParameterization_descriptor());
  if (!check.violations.empty()) return tl::unexpected(std::move(check.violations));
  core::MotionSpec spec;
  spec.duration_s = m.duration_s();
  spec.profile = m.profile() == v1::MOTION_PROFILE_S_CURVE ? core::ProfileShape::kSCurve
                                                           : core::ProfileShape::kTrapezoidal;
  if (m.has_ramp_fraction()) spec.ramp_fraction = m.ramp_fraction();
  if (m.has_ramp_time_s()) spec.ramp_time_s = m.ramp_time_s();
  spec.ramp_fraction_given = m.has_ramp_fraction();
  if (m.has_cycle_rate_hz()) spec.cycle_rate_hz = m.cycle_rate_hz();
  switch (m.time_parameterization()) {
    case v1::TIME_PARAMETERIZATION_TAYLOR_SECOND_ORDER:
      spec.time_parameterization = core::TimeParameterization::kTaylorSecondOrder;
      break;
    case v1::TIME_PARAMETERIZATION_TAYLOR_FIRST_ORDER:
      spec.time_parameterization = core::TimeParameterization::kTaylorFirstOrder;
      break;
    case v1::TIME_PARAMETERIZATION_LINEAR: spec.time_parameterization = core::TimeParameterization::kLinear; break;
    case v1::TIME_PARAMETERIZATION_SMOOTH: spec.time_parameterization = core::TimeParameterization::kSmooth; break;
    default: spec.time_parameterization = core::TimeParameterization::kArcLength; break;  // ARC_LENGTH, UNSPECIFIED
  }
  if (m.has_speed_scale()) spec.speed_scale = m.speed_scale();
  if (m.has_acceleration_scale()) {
    spec.acceleration_scale = m.acceleration_scale();
    // With a durationS it scales nothing, unless a robot.approach (timed by the limits)
    // comes first.
    const bool approach = request.has_path() && request.robot().approach() != v1::APPROACH_MOVE_UNSPECIFIED;
    if (m.duration_s() > 0.0 && !approach) {
      return tl::unexpected(core::Violations{
          {"motion.accelerationScale", "scales the limits of a timing by the limits (durationS 0, or a "
                                       "robot.approach): a motion with a durationS is timed by it instead"}});
    }
  }
  if (m.has_max_speed()) spec.max_speed = m.max_speed();
  if (m.has_max_acceleration()) spec.max_acceleration = m.max_acceleration();
  if (m.has_max_jerk()) spec.max_jerk = m.max_jerk();
  if (m.has_max_angular_speed()) spec.max_angular_speed = m.max_angular_speed();
  if (m.has_max_angular_acceleration()) spec.max_angular_acceleration = m.max_angular_acceleration();
  // A joint move's minimum time comes from the joint limits: core::plan_joint_move checks
  // the spec without asking for the Cartesian ones.
  if (request.has_joint_move()) return spec;
  // A minimum time that the time-optimal timing sets (planner::time_optimally_timed): the
  // limits given, and the joint ones with a robot, make it, so the Cartesian ones that the
  // other profiles need are optional here (the planner asks for maxAcceleration without a robot).
  core::MotionSpec checked = spec;
  const auto& timing = request.optimize().timing();
  if (spec.duration_s == 0.0 &&
      planner::time_optimally_timed(spec, request.has_robot(), timing.time_optimal(), timing.jerk_limited())) {
    checked.duration_s = 1.0;
    checked.profile = core::ProfileShape::kTrapezoidal;
  }
  auto violations = core::validate_motion(checked);
  if (!violations.empty()) return tl::unexpected(std::move(violations));
  return spec;
}

std::size_t samples_per_batch(const v1::PlanRequest& request) {
  return request.has_samples_per_batch() ? request.samples_per_batch() : kDefaultSamplesPerBatch;
}

std::size_t analysis_points(const v1::PlanRequest& request) {
  return request.has_analysis_points() ? request.analysis_points() : kDefaultAnalysisPoints;
}

void to_proto(const std::vector<core::FrameConstraints>& frames, v1::ConvertResponse& response) {
  for (const auto& f : frames) {
    auto* out = response.add_frames();
    set(out->mutable_position(), f.p_W);
    to_proto(f.approach, out->mutable_approach());
    to_proto(f.leave, out->mutable_leave());
  }
}

namespace {

void set(v1::Extremum* out, const core::Extremum& e) {
  out->set_value(e.value);
  out->set_u(e.u);
  out->set_s(e.s);
}

v1::PlanWarningCode to_proto(core::PathWarningCode code) {
  switch (code) {
    case core::PathWarningCode::kNearCusp: return v1::PLAN_WARNING_CODE_NEAR_CUSP;
    case core::PathWarningCode::kTightBend: return v1::PLAN_WARNING_CODE_TIGHT_BEND;
    case core::PathWarningCode::kTurnsBack: return v1::PLAN_WARNING_CODE_TURNS_BACK;
  }
  return v1::PLAN_WARNING_CODE_UNSPECIFIED;
}

}  // namespace

void to_proto(const core::Path& path, const std::vector<core::AchievedFrame>& achieved,
              const core::ClosedLoopError& closed_loop, const core::GeometryReport& geometry,
              v1::PlanResponse& response) {
  const std::size_t frame_count = path.frames.size();
  for (std::size_t i = 0; i < path.segment_count(); ++i) {
    auto* s = response.add_segments();
    const std::size_t to = (i + 1) % frame_count;
    s->set_index(static_cast<std::uint32_t>(i));
    s->set_from_frame(static_cast<std::uint32_t>(i));
    s->set_to_frame(static_cast<std::uint32_t>(to));
    s->set_arc_length(path.segment_lengths[i]);
    s->set_blend(to_proto(path.spec.blend));
    std::visit(
        [s](const auto& seg) {
          using T = std::decay_t<decltype(seg)>;
          if constexpr (std::is_same_v<T, core::BezierSegment>) {
            s->set_degree(static_cast<std::uint32_t>(seg.degree));
          } else {
            for (const auto& axis : seg.axes) s->add_trapezoid_orders(static_cast<std::uint32_t>(axis.n));
          }
        },
        path.segments[i]);
    s->set_start_order(static_cast<std::uint32_t>(path.frames[i].leave.order));
    s->set_end_order(static_cast<std::uint32_t>(path.frames[to].approach.order));
    const core::SegmentGeometry& g = geometry.segments[i];
    set(s->mutable_peak_curvature(), g.peak_curvature);
    set(s->mutable_peak_torsion(), g.peak_torsion);
    set(s->mutable_min_speed(), g.min_speed);
    s->set_turning(g.turning);
  }
  for (const auto& w : geometry.warnings) {
    auto* out = response.add_warnings();
    out->set_code(to_proto(w.code));
    out->set_segment(static_cast<std::uint32_t>(w.segment));
    out->set_u(w.u);
    out->set_s(w.s);
    out->set_value(w.value);
    out->set_message(w.message);
  }
  response.set_arc_length(path.length());

  const bool per_arc_length = path.spec.convention == core::DerivativeConvention::kPerArcLength;
  for (const auto& a : achieved) {
    auto* out = response.add_frames();
    set(out->mutable_position(), a.p_W);
    if (a.approach) to_proto(*a.approach, per_arc_length, out->mutable_approach());
    if (a.leave) to_proto(*a.leave, per_arc_length, out->mutable_leave());
  }

  auto* loop = response.mutable_closed_loop();
  loop->set_max_error(closed_loop.max_error);
  loop->set_worst_field(closed_loop.worst_field);
}

void to_proto(const core::Path& path, const std::vector<core::ProfilePoint>& points, v1::PathProfile& profile) {
  profile.mutable_points()->Reserve(static_cast<int>(points.size()));
  for (const auto& p : points) {
    auto* out = profile.add_points();
    out->set_u(p.u);
    out->set_s(p.s);
    out->set_segment(static_cast<std::uint32_t>(p.segment));
    set(out->mutable_position(), p.p_W);
    out->set_speed(p.geometry.speed);
    set_geometry(p.geometry, /*per_arc_length=*/true, out);
  }
  profile.set_arc_length(path.length());
}

Eigen::Isometry3d pose_from_proto(const v1::Pose& pose, const std::string& field, core::Violations& out) {
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  const Vector3d p = to_core(pose.position());
  if (!p.allFinite()) out.push_back({field + ".position", "must be finite"});
  X.translation() = p;
  if (pose.has_orientation()) {
    const auto& q = pose.orientation();
    Eigen::Quaterniond quat(q.w(), q.x(), q.y(), q.z());  // wire order (w, x, y, z) by name
    const double norm = quat.norm();
    if (!std::isfinite(norm) || std::abs(norm - 1.0) > kUnitQuaternionTolerance) {
      out.push_back({field + ".orientation", "must be a unit quaternion (w, x, y, z), got norm " + core::number(norm, 6)});
    } else {
      X.linear() = quat.normalized().toRotationMatrix();
    }
  }
  return X;
}

void to_proto(const Eigen::Isometry3d& X, v1::Pose& out) {
  to_proto(Vector3d(X.translation()), *out.mutable_position());
  const Eigen::Quaterniond q(X.linear());
  auto* o = out.mutable_orientation();
  o->set_w(q.w());
  o->set_x(q.x());
  o->set_y(q.y());
  o->set_z(q.z());
}

void to_proto(const Eigen::Vector3d& v, v1::Vec3& out) { set(&out, v); }

// --- robots ---------------------------------------------------------------------------------

namespace {

v1::LimitKind to_proto(core::LimitKind k) {
  switch (k) {
    case core::LimitKind::kPosition: return v1::LIMIT_KIND_POSITION;
    case core::LimitKind::kVelocity: return v1::LIMIT_KIND_VELOCITY;
    case core::LimitKind::kAcceleration: return v1::LIMIT_KIND_ACCELERATION;
    case core::LimitKind::kIk: return v1::LIMIT_KIND_IK;
    case core::LimitKind::kBranch: return v1::LIMIT_KIND_BRANCH;
    case core::LimitKind::kJerk: return v1::LIMIT_KIND_JERK;
  }
  return v1::LIMIT_KIND_UNSPECIFIED;
}

}  // namespace

namespace {

core::JointType joint_type_from_proto(v1::JointType type) {
  switch (type) {
    case v1::JOINT_TYPE_PRISMATIC: return core::JointType::kPrismatic;
    case v1::JOINT_TYPE_CONTINUOUS: return core::JointType::kContinuous;
    default: return core::JointType::kRevolute;
  }
}

v1::JointType to_proto(core::JointType type) {
  switch (type) {
    case core::JointType::kPrismatic: return v1::JOINT_TYPE_PRISMATIC;
    case core::JointType::kContinuous: return v1::JOINT_TYPE_CONTINUOUS;
    case core::JointType::kRevolute: break;
  }
  return v1::JOINT_TYPE_REVOLUTE;
}

}  // namespace

core::Expected<core::RobotModel> robot_model_from_proto(const v1::RobotModel& model, const std::string& prefix) {
  WireCheck check;
  core::RobotModel m;
  m.name = model.name();
  m.description = model.description();
  core::Violations poses;
  if (model.links_size() > 0 && model.joints_size() > 0) {
    check.violations.push_back({prefix + "joints", "and `links` are two ways of writing the chain: give one"});
  }
  if (model.joints_size() > 0) {  // a general chain
    if (model.dh_convention() != v1::DH_CONVENTION_UNSPECIFIED) {
      check.violations.push_back({prefix + "dhConvention", "is for `links` (a DH table); `joints` have none"});
    }
    for (int i = 0; i < model.joints_size(); ++i) {
      const auto& j = model.joints(i);
      const std::string at = prefix + "joints[" + std::to_string(i) + "]";
      check_enum(check, at + ".jointType", j.joint_type(), v1::JointType_descriptor());
      core::Joint joint;
      joint.name = j.name();
      joint.type = joint_type_from_proto(j.joint_type());
      if (j.has_origin()) joint.origin = pose_from_proto(j.origin(), at + ".origin", poses);
      if (j.has_axis()) joint.axis = to_core(j.axis());
      m.joints.push_back(std::move(joint));
    }
    if (model.has_flange()) m.flange = pose_from_proto(model.flange(), prefix + "flange", poses);
  } else {  // a DH table
    check_enum(check, prefix + "dhConvention", model.dh_convention(), v1::DhConvention_descriptor());
    if (model.has_flange()) {
      check.violations.push_back({prefix + "flange", "is for `joints` (a general chain); a DH table ends in frame n"});
    }
    core::DhTable table;
    table.convention = model.dh_convention() == v1::DH_CONVENTION_MODIFIED ? core::DhConvention::kModified
                                                                           : core::DhConvention::kStandard;
    for (int i = 0; i < model.links_size(); ++i) {
      const auto& l = model.links(i);
      check_enum(check, prefix + "links[" + std::to_string(i) + "].jointType", l.joint_type(),
                 v1::JointType_descriptor());
      table.links.push_back(
          {l.a(), l.alpha(), l.d(), l.theta(), joint_type_from_proto(l.joint_type()), l.offset(), l.name()});
    }
    core::set_dh(m, std::move(table));
  }
  for (const auto& l : model.limits()) {
    core::JointLimits limits{l.min_position(), l.max_position(), l.max_velocity(), l.max_acceleration(),
                             std::nullopt};
    if (l.has_max_jerk()) limits.max_jerk = l.max_jerk();
    m.limits.push_back(limits);
  }
  m.home.assign(model.home().begin(), model.home().end());
  if (model.has_base()) m.base = pose_from_proto(model.base(), prefix + "base", poses);
  if (model.has_tool()) m.tool = pose_from_proto(model.tool(), prefix + "tool", poses);
  for (auto& v : poses) check.violations.push_back(std::move(v));
  if (!check.violations.empty()) return tl::unexpected(std::move(check.violations));
  return m;
}

core::Expected<core::RobotModel> robot_model_from_json(std::string_view json) {
  v1::RobotModel model;
  const auto status = google::protobuf::util::JsonStringToMessage(std::string(json), &model);
  if (!status.ok()) {
    return tl::unexpected(core::Violations{{"", "is not a RobotModel in proto3 JSON: " + std::string(status.message())}});
  }
  if (model.name().empty()) return tl::unexpected(core::Violations{{"name", "is required: the model's name"}});
  auto read = robot_model_from_proto(model, "");
  if (!read) return read;
  if (core::Violations bad = core::validate_robot(*read); !bad.empty()) return tl::unexpected(std::move(bad));
  return read;
}

void to_proto(const core::RobotModel& model, v1::RobotModel& out) {
  out.set_name(model.name);
  out.set_description(model.description);
  if (model.dh) {  // written as a DH table: reported as one
    out.set_dh_convention(model.dh->convention == core::DhConvention::kModified ? v1::DH_CONVENTION_MODIFIED
                                                                                : v1::DH_CONVENTION_STANDARD);
    for (const auto& l : model.dh->links) {
      auto* link = out.add_links();
      link->set_a(l.a);
      link->set_alpha(l.alpha);
      link->set_d(l.d);
      link->set_theta(l.theta);
      link->set_joint_type(to_proto(l.type));
      link->set_offset(l.offset);
      link->set_name(l.name);
    }
  } else {
    for (const auto& j : model.joints) {
      auto* joint = out.add_joints();
      joint->set_name(j.name);
      joint->set_joint_type(to_proto(j.type));
      to_proto(j.origin, *joint->mutable_origin());
      to_proto(Vector3d(j.axis), *joint->mutable_axis());
    }
    to_proto(model.flange, *out.mutable_flange());
  }
  for (const auto& l : model.limits) {
    auto* limits = out.add_limits();
    limits->set_min_position(l.min_position);
    limits->set_max_position(l.max_position);
    limits->set_max_velocity(l.max_velocity);
    limits->set_max_acceleration(l.max_acceleration);
    if (l.max_jerk) limits->set_max_jerk(*l.max_jerk);
  }
  to_proto(model.base, *out.mutable_base());
  to_proto(model.tool, *out.mutable_tool());
  for (double q : model.home) out.add_home(q);
}

namespace {

// RobotSpec as the planner's value: a translation, with the violations of what cannot be
// translated (an unreadable inline model, a pose that is not one, an unknown approach) in
// `out`; the planner checks the values (planner::resolve_robot).
planner::RobotSpec robot_spec_from_proto(const v1::RobotSpec& spec, core::Violations& out) {
  planner::RobotSpec s;
  switch (spec.model_source_case()) {
    case v1::RobotSpec::kName: s.source = planner::RobotByName{spec.name()}; break;
    case v1::RobotSpec::kModel: {
      auto model = robot_model_from_proto(spec.model(), "robot.model.");
      if (!model) out.insert(out.end(), model.error().begin(), model.error().end());
      s.source = planner::InlineRobot{model ? std::optional<core::RobotModel>(std::move(*model)) : std::nullopt};
      break;
    }
    case v1::RobotSpec::kUrdf: s.source = planner::UrdfRobot{spec.urdf()}; break;
    case v1::RobotSpec::MODEL_SOURCE_NOT_SET: break;
  }
  s.base_link = spec.base_link();
  s.tip_link = spec.tip_link();
  for (const auto& l : spec.joint_limits()) {
    planner::NamedLimits limits{l.joint(), std::nullopt, std::nullopt, std::nullopt};
    if (l.has_max_velocity()) limits.max_velocity = l.max_velocity();
    if (l.has_max_acceleration()) limits.max_acceleration = l.max_acceleration();
    if (l.has_max_jerk()) limits.max_jerk = l.max_jerk();
    s.joint_limits.push_back(std::move(limits));
  }
  if (spec.has_base()) s.base = pose_from_proto(spec.base(), "robot.base", out);
  if (spec.has_tool()) s.tool = pose_from_proto(spec.tool(), "robot.tool", out);
  s.report_only = spec.report_only();
  if (spec.has_branch_tolerance()) s.branch_tolerance = spec.branch_tolerance();
  if (spec.has_start_position_tolerance()) s.start_position_tolerance = spec.start_position_tolerance();
  if (spec.has_start_orientation_tolerance()) s.start_orientation_tolerance = spec.start_orientation_tolerance();
  if (spec.has_velocity_scale()) s.velocity_scale = spec.velocity_scale();
  if (spec.has_acceleration_scale()) s.acceleration_scale = spec.acceleration_scale();
  switch (spec.approach()) {
    case v1::APPROACH_MOVE_UNSPECIFIED: s.approach = planner::Approach::kNone; break;
    case v1::APPROACH_MOVE_JOINT: s.approach = planner::Approach::kJoint; break;
    case v1::APPROACH_MOVE_LINEAR: s.approach = planner::Approach::kLinear; break;
    default:
      out.push_back({"robot.approach", "unknown value " + std::to_string(spec.approach()) +
                                           "; use APPROACH_MOVE_JOINT or APPROACH_MOVE_LINEAR"});
  }
  s.initial_joints.assign(spec.initial_joints().begin(), spec.initial_joints().end());
  return s;
}

}  // namespace

core::Expected<planner::Robot> robot_from_request(const v1::RobotSpec& spec, const RobotCatalog& catalog,
                                                  bool motion, const planner::StopAt& stop_at) {
  core::Violations out;
  const planner::RobotSpec translated = robot_spec_from_proto(spec, out);
  auto robot = planner::resolve_robot(translated, catalog, motion, stop_at);
  if (!robot) out.insert(out.end(), robot.error().begin(), robot.error().end());
  if (!out.empty()) return tl::unexpected(std::move(out));
  return robot;
}

void to_proto(const core::BindingStretch& stretch, v1::BindingStretch& out) {
  switch (stretch.kind) {
    case core::BindingKind::kJointVelocity: out.set_kind(v1::BINDING_KIND_JOINT_VELOCITY); break;
    case core::BindingKind::kJointAcceleration: out.set_kind(v1::BINDING_KIND_JOINT_ACCELERATION); break;
    case core::BindingKind::kJointJerk: out.set_kind(v1::BINDING_KIND_JOINT_JERK); break;
    case core::BindingKind::kCartesianSpeed: out.set_kind(v1::BINDING_KIND_CARTESIAN_SPEED); break;
    case core::BindingKind::kTangentialAcceleration:
      out.set_kind(v1::BINDING_KIND_CARTESIAN_TANGENTIAL_ACCELERATION);
      break;
    case core::BindingKind::kCentripetalAcceleration:
      out.set_kind(v1::BINDING_KIND_CARTESIAN_CENTRIPETAL_ACCELERATION);
      break;
    case core::BindingKind::kAngularSpeed: out.set_kind(v1::BINDING_KIND_ANGULAR_SPEED); break;
    case core::BindingKind::kAngularAcceleration: out.set_kind(v1::BINDING_KIND_ANGULAR_ACCELERATION); break;
  }
  out.set_joint(static_cast<std::uint32_t>(stretch.joint));
  out.set_t_start(stretch.t_start);
  out.set_t_end(stretch.t_end);
  out.set_s_start(stretch.s_start);
  out.set_s_end(stretch.s_end);
  out.set_usage(stretch.usage);
  out.set_value(stretch.value);
  out.set_limit(stretch.limit);
}

void to_proto(const core::LimitEvent& event, v1::LimitEvent& out) {
  out.set_kind(to_proto(event.kind));
  out.set_joint(static_cast<std::uint32_t>(event.joint));
  out.set_sample(event.sample);
  out.set_t(event.t);
  out.set_value(event.value);
  out.set_limit(event.limit);
  out.set_margin(event.margin);
}

std::string describe(const core::LimitEvent& e) {
  const std::string where = " at t = " + core::number(e.t, 6) + " s (sample " + std::to_string(e.sample) + ")";
  const std::string joint = "joint " + std::to_string(e.joint);
  switch (e.kind) {
    case core::LimitKind::kPosition:
      if (e.margin >= 0.0) {  // at (or near) the limit, named as the cause of what follows
        const bool at = e.margin <= core::kLimitTolerance * std::max(1.0, std::abs(e.limit));
        return joint + " position " + core::number(e.value, 6) +
               (at ? " is at its limit " + core::number(e.limit, 6) + where + ", held there"
                   : " is " + core::number(e.margin, 3) + " from its limit " + core::number(e.limit, 6) + where) +
               ": the path needs more of its range";
      }
      return joint + " position " + core::number(e.value, 6) + " is outside its limits" + where + " (by " + core::number(-e.margin, 6) + ")";
    case core::LimitKind::kVelocity:
      return joint + " speed " + core::number(e.value, 6) + " exceeds maxVelocity " + core::number(e.limit, 6) + where;
    case core::LimitKind::kAcceleration:
      return joint + " acceleration " + core::number(e.value, 6) + " exceeds maxAcceleration " + core::number(e.limit, 6) + where;
    case core::LimitKind::kJerk:
      return joint + " jerk " + core::number(e.value, 6) + " (the change of its acceleration over the sample step) exceeds maxJerk " +
             core::number(e.limit, 6) + where + ": an acceleration step (a trapezoidal profile); MOTION_PROFILE_S_CURVE or durationS 0 keeps the jerk limits";
    case core::LimitKind::kIk:
      return "the inverse kinematics did not converge" + where + " (position residual " + core::number(e.value, 6) +
             " m): the pose is out of reach or at a singularity";
    case core::LimitKind::kBranch:
      return "joint interpolation strays " + core::number(e.value, 6) + " m from the path" + where +
             " (tolerance " + core::number(e.limit, 6) + " m): a branch change or a singularity crossing";
  }
  return "limit event" + where;
}

void to_proto(const std::string& robot_name, const core::JointMotionReport& report, v1::RobotReport& out) {
  out.set_name(robot_name);
  out.set_samples(report.samples);
  out.set_converged_samples(report.converged_samples);
  out.set_max_ik_position_error(report.max_position_error);
  out.set_max_ik_orientation_error(report.max_orientation_error);
  out.set_feasible(report.feasible());
  for (const auto& v : report.violations) to_proto(v, *out.add_violations());
  if (report.converged_samples == 0) {
    // No joint value was measured: the figures below would be their +-infinity starts.
    for (std::size_t j = 0; j < report.joints.size(); ++j) out.add_joints()->set_joint(static_cast<std::uint32_t>(j));
    return;
  }
  for (std::size_t j = 0; j < report.joints.size(); ++j) {
    const auto& u = report.joints[j];
    auto* r = out.add_joints();
    r->set_joint(static_cast<std::uint32_t>(j));
    r->set_min_position(u.min_position);
    r->set_max_position(u.max_position);
    r->set_peak_velocity(u.peak_velocity);
    r->set_peak_acceleration(u.peak_acceleration);
    r->set_velocity_usage(u.velocity_usage);
    r->set_acceleration_usage(u.acceleration_usage);
    if (std::isfinite(u.position_margin)) r->set_position_margin(u.position_margin);  // none: continuous
  }
  if (std::isfinite(report.tightest_position.margin)) {  // every joint continuous: none
    to_proto(report.tightest_position, *out.mutable_tightest_position());
  }
  to_proto(report.tightest_velocity, *out.mutable_tightest_velocity());
  to_proto(report.tightest_acceleration, *out.mutable_tightest_acceleration());
  out.set_max_midpoint_deviation(report.max_midpoint_deviation);
  out.set_max_midpoint_deviation_t(report.max_midpoint_deviation_t);
  out.set_min_manipulability(report.min_manipulability);
  out.set_min_manipulability_t(report.min_manipulability_t);
  for (const auto& b : report.binding) to_proto(b, *out.add_binding());
}

core::Expected<planner::Geometry> joint_move_from_request(const v1::PlanRequest& request,
                                                          const core::JointVector& seed) {
  const auto& move = request.joint_move();
  std::vector<double> start;
  if (move.start_size() == 0) {
    start.assign(seed.data(), seed.data() + seed.size());
  } else {
    start.assign(move.start().begin(), move.start().end());
  }
  const bool joints = move.goal_size() > 0;
  if (joints == move.has_goal_pose()) {
    return tl::unexpected(core::Violations{
        {"jointMove.goal", joints ? "give `goal` (joint values) or `goalPose` (a tool pose), not both"
                                  : "is required: the joint values at the goal, one per joint (or `goalPose`)"}});
  }
  if (joints) return planner::Geometry(core::JointMoveSpec{std::move(start), {move.goal().begin(), move.goal().end()}});
  core::Violations out;
  const Eigen::Isometry3d goal = pose_from_proto(move.goal_pose(), "jointMove.goalPose", out);
  if (goal.translation().allFinite() && goal.translation().cwiseAbs().maxCoeff() > core::PathLimits{}.max_coordinate) {
    out.push_back({"jointMove.goalPose.position",
                   "coordinates must lie within " + core::number(core::PathLimits{}.max_coordinate) + " m of the origin"});
  }
  if (!out.empty()) return tl::unexpected(std::move(out));
  return planner::Geometry(planner::JointMoveToPose{std::move(start), goal});
}

core::Expected<planner::Geometry> linear_move_from_request(const v1::PlanRequest& request,
                                                           const planner::Robot* robot) {
  const auto& move = request.linear_move();
  core::Violations out;
  core::LinearMoveSpec spec;
  auto tool_pose = [](const v1::Pose& pose) {
    core::ToolPose p;
    p.p_WT = to_core(pose.position());
    if (pose.has_orientation()) {
      const auto& q = pose.orientation();
      p.q_WT = Eigen::Quaterniond(q.w(), q.x(), q.y(), q.z());  // by name; core checks its norm
    }
    return p;
  };
  if (move.has_start()) {
    spec.start = tool_pose(move.start());
  } else if (robot != nullptr) {
    const Eigen::Isometry3d X = core::forward_kinematics(robot->model, robot->seed);
    spec.start.p_WT = X.translation();
    spec.start.q_WT = Eigen::Quaterniond(X.linear());
  } else {
    out.push_back({"linearMove.start", "is required without a robot (with one, the pose of its initialJoints)"});
  }
  const bool joints = move.goal_joints_size() > 0;
  if (joints && move.has_goal()) {
    out.push_back({"linearMove.goal", "give `goal` (a tool pose) or `goalJoints` (joint values), not both"});
  } else if (joints) {
    if (robot == nullptr) out.push_back({"linearMove.goalJoints", "needs `robot`: the joints belong to a robot model"});
    for (int i = 0; i < move.goal_joints_size(); ++i) {
      if (!std::isfinite(move.goal_joints(i))) {
        out.push_back({"linearMove.goalJoints[" + std::to_string(i) + "]",
                       "must be finite, got " + core::number(move.goal_joints(i))});
      }
    }
  } else if (move.has_goal()) {
    spec.goal = tool_pose(move.goal());
  } else {
    out.push_back({"linearMove.goal", "is required: the tool pose at the end of the move (or `goalJoints`)"});
  }
  if (!out.empty()) return tl::unexpected(std::move(out));
  if (joints) {
    return planner::Geometry(
        planner::LinearMoveToJoints{spec.start, {move.goal_joints().begin(), move.goal_joints().end()}});
  }
  return planner::Geometry(spec);
}

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
}

// --- optimisation --------------------------------------------------------------------------

namespace {

v1::OptimizerStatus to_proto(optim::OptimizerStatus status) {
  switch (status) {
    case optim::OptimizerStatus::kConverged: return v1::OPTIMIZER_STATUS_CONVERGED;
    case optim::OptimizerStatus::kIterationLimit: return v1::OPTIMIZER_STATUS_ITERATION_LIMIT;
    case optim::OptimizerStatus::kTimeLimit: return v1::OPTIMIZER_STATUS_TIME_LIMIT;
    case optim::OptimizerStatus::kNoImprovement: return v1::OPTIMIZER_STATUS_NO_IMPROVEMENT;
    case optim::OptimizerStatus::kFailed: return v1::OPTIMIZER_STATUS_FAILED;
  }
  return v1::OPTIMIZER_STATUS_UNSPECIFIED;
}

// The fields every optimiser report has.
template <class Report>
void set_report(const optim::OptimizerReport& r, Report& out) {
  out.set_objective_before(r.objective_before);
  out.set_objective_after(r.objective_after);
  out.set_iterations(static_cast<std::uint32_t>(std::max(r.iterations, 0)));
  out.set_status(to_proto(r.status));
  out.set_seconds(r.seconds);
  out.set_message(r.message);
}

}  // namespace

core::Expected<double> optimize_budget(const v1::PlanRequest& request, double max_seconds) {
  const auto& o = request.optimize();
  if (!o.has_time_budget_s()) return std::min(kDefaultOptimizeBudgetS, max_seconds);
  if (!(std::isfinite(o.time_budget_s()) && o.time_budget_s() > 0.0)) {
    return tl::unexpected(
        core::Violations{{"optimize.timeBudgetS", "must be a finite time > 0 s when given, got " + core::number(o.time_budget_s(), 6)}});
  }
  if (o.time_budget_s() > max_seconds) {
    return tl::unexpected(core::Violations{{"optimize.timeBudgetS", "asks for " + core::number(o.time_budget_s(), 6) +
                                                                        " s; this server allows at most " +
                                                                        core::number(max_seconds, 6) +
                                                                        " s per call (geotrajd --max-optimize-seconds)"}});
  }
  return o.time_budget_s();
}

core::Expected<optim::TangentScaleOptions> tangent_scale_options(const v1::PlanRequest& request) {
  const auto& t = request.optimize().tangent_scales();
  WireCheck check;
  check_enum(check, "optimize.tangentScales.objective", t.objective(), v1::TangentScaleObjective_descriptor());
  if (!check.violations.empty()) return tl::unexpected(std::move(check.violations));
  optim::TangentScaleOptions options;
  switch (t.objective()) {
    case v1::TANGENT_SCALE_OBJECTIVE_PEAK_CURVATURE: options.objective = optim::TangentScaleObjective::kPeakCurvature; break;
    case v1::TANGENT_SCALE_OBJECTIVE_PEAK_TORSION: options.objective = optim::TangentScaleObjective::kPeakTorsion; break;
    case v1::TANGENT_SCALE_OBJECTIVE_ARC_LENGTH: options.objective = optim::TangentScaleObjective::kArcLength; break;
    default: options.objective = optim::TangentScaleObjective::kBendingEnergy; break;  // BENDING_ENERGY, UNSPECIFIED
  }
  if (t.has_min_scale()) options.min_scale = t.min_scale();
  if (t.has_max_scale()) options.max_scale = t.max_scale();
  if (t.has_length_weight()) options.length_weight = t.length_weight();
  return options;  // ranges: optim::optimize_tangent_scales names them
}

core::Expected<optim::BreakpointOptions> breakpoint_options(const v1::PlanRequest& request) {
  const auto& b = request.optimize().breakpoints();
  WireCheck check;
  check_enum(check, "optimize.breakpoints.objective", b.objective(), v1::BreakpointObjective_descriptor());
  if (!check.violations.empty()) return tl::unexpected(std::move(check.violations));
  optim::BreakpointOptions options;
  switch (b.objective()) {
    case v1::BREAKPOINT_OBJECTIVE_PEAK_CURVATURE: options.objective = optim::BreakpointObjective::kPeakCurvature; break;
    case v1::BREAKPOINT_OBJECTIVE_PEAK_DERIVATIVES: options.objective = optim::BreakpointObjective::kPeakDerivatives; break;
    default: options.objective = optim::BreakpointObjective::kPeakTorsion; break;  // PEAK_TORSION, UNSPECIFIED
  }
  return options;
}

void to_proto(const optim::TangentScaleResult& result, v1::TangentScaleReport& out) {
  set_report(result.report, out);
  for (double scale : result.scales) out.add_tangent_scales(scale);
  out.set_length_weight(result.length_weight);
}

void to_proto(const planner::TimingReport& report, v1::TimingReport& out) {
  set_report(report.report, out);
  for (const auto& b : report.binding) to_proto(b, *out.add_binding());
  out.set_check_rate_hz(report.check_rate_hz);
  out.set_worst_limit_usage(report.worst_limit_usage);
  out.set_refinements(static_cast<std::uint32_t>(std::max(0, report.refinements)));
  out.set_duration_grid_error_s(report.duration_grid_error_s);
}

void to_proto(const optim::BreakpointResult& result, v1::BreakpointReport& out) {
  set_report(result.report, out);
  for (const auto& b : result.breakpoints) {
    auto* seg = out.add_breakpoints();
    seg->set_segment(b.segment);
    for (double x : b.all) seg->add_all(x);
    for (double x : b.x) seg->add_x(x);
    for (double x : b.y) seg->add_y(x);
    for (double x : b.z) seg->add_z(x);
  }
}

namespace {

core::Violations joined(core::Violations a, const core::Violations& b) {
  a.insert(a.end(), b.begin(), b.end());
  return a;
}

// The path of a request and its optimisers (optimize.*), every violation of both together.
core::Expected<planner::Request> path_request(const v1::PlanRequest& request, const ServiceLimits& limits,
                                              planner::Request out) {
  auto spec = path_from_request(request, limits);
  core::Violations violations = spec ? core::Violations{} : spec.error();
  if (request.has_optimize()) {
    planner::Optimize optimize;
    const auto& o = request.optimize();
    if (auto budget = optimize_budget(request, limits.max_optimize_seconds)) {
      optimize.budget_s = *budget;
    } else {
      violations = joined(std::move(violations), budget.error());
    }
    if (o.has_tangent_scales()) {
      auto options = tangent_scale_options(request);
      if (options) {
        optimize.tangent_scales = std::move(*options);
      } else {
        violations = joined(std::move(violations), options.error());
      }
    }
    if (o.has_breakpoints()) {
      auto options = breakpoint_options(request);
      if (options) {
        optimize.breakpoints = std::move(*options);
      } else {
        violations = joined(std::move(violations), options.error());
      }
    }
    optimize.time_optimal = o.timing().time_optimal();
    optimize.jerk_limited = o.timing().jerk_limited();
    out.optimize = std::move(optimize);
  }
  if (!violations.empty()) return tl::unexpected(std::move(violations));
  out.geometry = std::move(*spec);
  return out;
}

constexpr int kMaxSequenceSteps = 64;

// The fields a step's own motion gives, by their API names ("maxSpeed", ...).
std::vector<std::string> given_motion_fields(const v1::SequenceStep& step) {
  std::vector<const google::protobuf::FieldDescriptor*> fields;
  if (step.has_motion()) v1::MotionSpec::GetReflection()->ListFields(step.motion(), &fields);
  std::vector<std::string> names;
  for (const auto* f : fields) names.push_back(f->camelcase_name());
  return names;
}

// Whether a step's own motion gives the field `field` names ("motion.maxSpeed"; "motion"
// alone: the step has a motion), so that a violation is named where the user wrote it.
bool step_gives(const v1::SequenceStep& step, std::string_view field) {
  if (!step.has_motion()) return false;
  if (field == "motion") return true;
  field.remove_prefix(std::string_view("motion.").size());
  const auto given = given_motion_fields(step);
  return std::find(given.begin(), given.end(), field.substr(0, field.find_first_of(".["))) != given.end();
}

// A violation of a step's own request, named from the root: the step's fields under
// `sequence[i].` (a motion field only when the step's motion gives it; else the request's
// `motion`, which it took the field from), the request's as they are.
core::FieldViolation in_step(core::FieldViolation v, int i, const v1::SequenceStep& step) {
  const auto starts = [&v](std::string_view prefix) {
    return v.field.rfind(prefix, 0) == 0 && (v.field.size() == prefix.size() || v.field[prefix.size()] == '.' ||
                                             v.field[prefix.size()] == '[');
  };
  if (starts("path") || starts("jointMove") || starts("linearMove") || (starts("motion") && step_gives(step, v.field))) {
    v.field = "sequence[" + std::to_string(i) + "]." + v.field;
  }
  return v;
}

// The rate a step streams at and the field that set it: the step's motion, else the
// request's, else core::MotionSpec's default.
std::pair<double, std::string> step_rate(const v1::PlanRequest& request, int i) {
  const auto& step = request.sequence(i);
  if (step.has_motion() && step.motion().has_cycle_rate_hz()) {
    return {step.motion().cycle_rate_hz(), "sequence[" + std::to_string(i) + "].motion.cycleRateHz"};
  }
  if (request.has_motion() && request.motion().has_cycle_rate_hz()) {
    return {request.motion().cycle_rate_hz(), "motion.cycleRateHz"};
  }
  return {core::MotionSpec{}.cycle_rate_hz, "the default"};
}

// One path, move or line (a request's, or a sequence step's); `robot`, when given, is the
// request's robot already resolved (a sequence resolves it once for all its steps).
core::Expected<planner::Request> single_from_proto(const v1::PlanRequest& request, const RobotCatalog& catalog,
                                                   const ServiceLimits& limits, RequestUse use,
                                                   const planner::StopAt& stop_at,
                                                   std::shared_ptr<const planner::Robot> robot);

// PlanRequest.sequence: each step converted as a request of its own (the request's robot,
// motion unless the step gives one, optimize for paths), every violation named from the root.
core::Expected<planner::Request> sequence_from_proto(const v1::PlanRequest& request, const RobotCatalog& catalog,
                                                     const ServiceLimits& limits, RequestUse use,
                                                     const planner::StopAt& stop_at) {
  core::Violations violations;
  if (use == RequestUse::kAnalyze) {
    return tl::unexpected(core::Violations{
        {"sequence", "AnalyzePath analyses one `path`: send each path of the sequence on its own"}});
  }
  if (request.has_path() || request.has_joint_move() || request.has_linear_move()) {
    violations.push_back({"sequence", "give a sequence, or one `path`, `jointMove` or `linearMove`, not both"});
  }
  if (request.sequence_size() > kMaxSequenceSteps) {
    violations.push_back({"sequence", "has " + std::to_string(request.sequence_size()) + " steps; at most " +
                                          std::to_string(kMaxSequenceSteps) + " are planned in one request"});
  }
  if (!violations.empty()) return tl::unexpected(std::move(violations));
  // The robot, once for every step (a URDF is read once, not once a step); the steps of a
  // sequence whose robot does not resolve are not checked.
  std::shared_ptr<const planner::Robot> robot;
  if (request.has_robot()) {
    auto resolved = robot_from_request(request.robot(), catalog, true, stop_at);
    if (!resolved) return tl::unexpected(std::move(resolved.error()));
    robot = std::make_shared<const planner::Robot>(std::move(*resolved));
  }
  planner::Request out;
  bool any_path = false, any_line = false;
  bool first_rate_named = false;
  for (int i = 0; i < request.sequence_size(); ++i) {
    const auto& step = request.sequence(i);
    const std::string field = "sequence[" + std::to_string(i) + "]";
    if (!step.has_motion() && !request.has_motion()) {
      violations.push_back({field + ".motion", "is required: a sequence step's timing, or the request's `motion`"});
      continue;
    }
    v1::PlanRequest sub;
    if (request.has_robot()) *sub.mutable_robot() = request.robot();
    // The step's motion over the request's: every field the step does not give, the
    // request's motion gives.
    *sub.mutable_motion() = request.motion();
    if (step.has_motion()) sub.mutable_motion()->MergeFrom(step.motion());
    // The request's accelerationScale scales the steps the limits time; a step timed by its
    // own durationS takes none (unless it gives one, which is then refused as at the top).
    if (step.motion().duration_s() > 0.0 && !step.motion().has_acceleration_scale()) {
      sub.mutable_motion()->clear_acceleration_scale();
    }
    sub.set_pacing(request.pacing());
    if (request.has_samples_per_batch()) sub.set_samples_per_batch(request.samples_per_batch());
    bool start_given = false;
    if (step.has_path()) {
      *sub.mutable_path() = step.path();
      if (request.has_optimize()) *sub.mutable_optimize() = request.optimize();
      any_path = true;
    }
    if (step.has_joint_move()) {
      *sub.mutable_joint_move() = step.joint_move();
      start_given = step.joint_move().start_size() > 0;
    }
    if (step.has_linear_move()) {
      *sub.mutable_linear_move() = step.linear_move();
      any_line = true;
      if (request.has_optimize()) {  // its timing (a line has no shape to optimise)
        *sub.mutable_optimize()->mutable_timing() = request.optimize().timing();
        if (request.optimize().has_time_budget_s()) sub.mutable_optimize()->set_time_budget_s(request.optimize().time_budget_s());
      }
      start_given = step.linear_move().has_start();
      // After the first step an absent start is where the previous step ends, known when
      // the planner gets there: a placeholder the planner replaces.
      if (!start_given && i > 0) sub.mutable_linear_move()->mutable_start()->mutable_orientation()->set_w(1.0);
    }
    double blend = 0.0;
    if (step.has_blend_tolerance()) {
      blend = step.blend_tolerance();
      if (!(std::isfinite(blend) && blend >= 0.0 && blend <= 1e3)) {
        violations.push_back({field + ".blendTolerance", "must be a distance in [0, 1000] m, got " + core::number(blend)});
      } else if (blend > 0.0 && i + 1 == request.sequence_size()) {
        violations.push_back({field + ".blendTolerance", "the last step has no corner after it to blend"});
      }
    }
    if (const auto [rate, source] = step_rate(request, i); i > 0 && rate != step_rate(request, 0).first) {
      const auto [first_rate, first_source] = step_rate(request, 0);
      // Named on the field the user gave: this step's, else (once) the first step's.
      const bool own = source.starts_with("sequence[");
      if (own || !first_rate_named) {
        violations.push_back({own ? source : first_source,
                              "is " + core::number(own ? rate : first_rate) +
                                  " Hz; every step of a sequence streams at one rate, " +
                                  core::number(own ? first_rate : rate) + " Hz (" + (own ? first_source : source) +
                                  ")"});
        first_rate_named = first_rate_named || !own;
      }
    }
    const int kinds = int(step.has_path()) + int(step.has_joint_move()) + int(step.has_linear_move());
    if (kinds != 1) {
      violations.push_back({field, kinds == 0 ? "is empty: give a `path`, a `jointMove` or a `linearMove`"
                                              : "give exactly one of `path`, `jointMove` and `linearMove`"});
      continue;
    }
    auto converted = single_from_proto(sub, catalog, limits, use, stop_at, robot);
    if (!converted) {
      for (auto& v : converted.error()) {
        auto named = in_step(std::move(v), i, step);
        const bool seen = std::any_of(violations.begin(), violations.end(), [&named](const core::FieldViolation& w) {
          return w.field == named.field && w.description == named.description;
        });
        if (!seen) violations.push_back(std::move(named));
      }
      continue;
    }
    if (!out.robot) out.robot = converted->robot;
    if (!out.optimize) out.optimize = converted->optimize;
    if (!out.motion) out.motion = converted->motion;
    out.sequence.push_back(
        planner::Step{std::move(converted->geometry), *converted->motion, step.has_motion(), given_motion_fields(step),
                      start_given, blend, {}});
  }
  // optimize.timing times the paths and lines (a blended chain of lines included); the
  // shape optimisers need a path.
  if (request.has_optimize() && !any_path && !any_line) {
    violations.push_back({"optimize", "applies to the paths and lines of a sequence, and this one has neither"});
  } else if (request.has_optimize() && !any_path &&
             (request.optimize().has_tangent_scales() || request.optimize().has_breakpoints())) {
    violations.push_back({request.optimize().has_tangent_scales() ? "optimize.tangentScales" : "optimize.breakpoints",
                          "shapes the paths of a sequence, and this one has none (optimize.timing times its lines)"});
  }
  if (!violations.empty()) return tl::unexpected(std::move(violations));
  return out;
}

core::Expected<planner::Request> single_from_proto(const v1::PlanRequest& request, const RobotCatalog& catalog,
                                                   const ServiceLimits& limits, RequestUse use,
                                                   const planner::StopAt& stop_at,
                                                   std::shared_ptr<const planner::Robot> robot) {
  planner::Request out;
  const bool moves = request.has_joint_move() || request.has_linear_move();
  if (!request.has_motion()) {
    if (use == RequestUse::kStream) {
      return tl::unexpected(core::Violations{
          {"motion", "is required to stream samples: give durationS (s), or the limits for a minimum-time motion"}});
    }
    if (use == RequestUse::kPlan && (request.has_robot() || moves)) {
      return tl::unexpected(core::Violations{
          {"motion", "is required with a robot or a move: give durationS (s), or the limits for a minimum-time move"}});
    }
  }
  // Without a motion (PlanTrajectory) or for an analysis, only the path and its optimisers.
  if (use == RequestUse::kAnalyze || !request.has_motion()) return path_request(request, limits, std::move(out));
  core::Violations violations;
  if (use == RequestUse::kStream && !v1::StreamPacing_IsValid(request.pacing())) {
    violations.push_back({"pacing", "unknown value " + std::to_string(request.pacing()) +
                                        "; use STREAM_PACING_AS_FAST_AS_POSSIBLE or STREAM_PACING_REAL_TIME"});
  }
  const int kinds = int(request.has_path()) + int(request.has_joint_move()) + int(request.has_linear_move());
  if (kinds != 1) {
    violations.push_back({"path", kinds == 0
                                      ? "is required: give the key frames of a `path`, or a `jointMove` or a `linearMove`"
                                      : "give exactly one of `path`, `jointMove` and `linearMove`"});
    return tl::unexpected(std::move(violations));
  }
  if (request.has_optimize() && request.has_joint_move()) {
    violations.push_back({"optimize", "applies to a `path` or a linearMove's timing: a jointMove is timed by its "
                                      "slowest joint already"});
  }
  if (request.has_optimize() && request.has_linear_move()) {
    const auto& o = request.optimize();
    if (o.has_tangent_scales() || o.has_breakpoints()) {
      violations.push_back({o.has_tangent_scales() ? "optimize.tangentScales" : "optimize.breakpoints",
                            "shapes a path: a linearMove is straight (optimize.timing applies to it)"});
    }
    planner::Optimize optimize;
    if (auto budget = optimize_budget(request, limits.max_optimize_seconds)) {
      optimize.budget_s = *budget;
    } else {
      violations = joined(std::move(violations), budget.error());
    }
    optimize.time_optimal = o.timing().time_optimal();
    optimize.jerk_limited = o.timing().jerk_limited();
    out.optimize = optimize;
  }
  if (auto motion = motion_from_request(request)) {
    out.motion = std::move(*motion);
  } else {
    violations = joined(std::move(violations), motion.error());
  }
  if (robot) {
    out.robot = std::move(robot);
  } else if (request.has_robot()) {
    if (auto resolved = robot_from_request(request.robot(), catalog, true, stop_at)) {
      out.robot = std::make_shared<const planner::Robot>(std::move(*resolved));
    } else {
      violations = joined(std::move(violations), resolved.error());
    }
  }
  if (request.has_joint_move()) {
    if (!request.has_robot()) {
      violations.push_back({"robot", "is required by a jointMove: the joints belong to a robot model"});
    }
    if (!violations.empty()) return tl::unexpected(std::move(violations));
    auto move = joint_move_from_request(request, out.robot->seed);
    if (!move) return tl::unexpected(std::move(move.error()));
    out.geometry = std::move(*move);
    return out;
  }
  // Following a Cartesian pose (a path or a straight line) takes six joints at least.
  if (out.robot && out.robot->model.dof() < 6) {
    const auto& spec = request.robot();
    violations.push_back({spec.model_source_case() == v1::RobotSpec::kUrdf ? "robot.urdf"
                          : !spec.has_model()                            ? "robot"
                          : spec.model().joints_size() > 0               ? "robot.model.joints"
                                                                         : "robot.model.links",
                          "the robot has " + std::to_string(out.robot->model.dof()) +
                              " joints; following a tool pose (position and orientation) needs at least 6"});
  }
  if (request.has_linear_move()) {
    if (!violations.empty()) return tl::unexpected(std::move(violations));
    auto move = linear_move_from_request(request, out.robot.get());
    if (!move) return tl::unexpected(std::move(move.error()));
    out.geometry = std::move(*move);
    return out;
  }
  // The path's and the optimisers' own violations with these, so that one answer lists all.
  auto converted = path_request(request, limits, std::move(out));
  if (violations.empty()) return converted;
  return tl::unexpected(converted ? std::move(violations) : joined(std::move(converted.error()), violations));
}

}  // namespace

core::Expected<planner::Request> request_from_proto(const v1::PlanRequest& request, const RobotCatalog& catalog,
                                                     const ServiceLimits& limits, RequestUse use,
                                                     const planner::StopAt& stop_at) {
  if (request.sequence_size() > 0) return sequence_from_proto(request, catalog, limits, use, stop_at);
  return single_from_proto(request, catalog, limits, use, stop_at, nullptr);
}

void to_proto(const planner::OptimizerReports& reports, v1::OptimizationReport& out) {
  if (reports.tangent_scales) to_proto(*reports.tangent_scales, *out.mutable_tangent_scales());
  if (reports.breakpoints) to_proto(*reports.breakpoints, *out.mutable_breakpoints());
  if (reports.timing) to_proto(*reports.timing, *out.mutable_timing());
}

void to_proto(const planner::Plan& plan, bool with_optimization, v1::PlanResponse& response) {
  if (plan.path_report) {
    const auto& r = *plan.path_report;
    to_proto(*plan.followed_path(), r.achieved, r.closed_loop, r.geometry, response);
  }
  if (with_optimization) to_proto(plan.optimizers, *response.mutable_optimization());
  if (plan.joints) to_proto(plan.robot->model.name, *plan.joints, *response.mutable_robot());
  if (plan.joints && plan.default_jerk) {
    auto& out = *response.mutable_robot()->mutable_default_jerk();
    out.set_ramp_s(plan.default_jerk->ramp_s);
    for (std::size_t i : plan.default_jerk->joints) out.add_joints(static_cast<std::uint32_t>(i));
    for (double j : plan.default_jerk->max_jerk) out.add_max_jerk(j);
    out.set_message(plan.default_jerk->message);
  }
  if (!plan.trajectory) return;
  const auto& trajectory = *plan.trajectory;
  const auto tool = plan.tool.value_or(planner::ToolPeaks{});
  auto& summary = *response.mutable_motion();
  summary.set_duration_s(core::duration(trajectory));
  summary.set_sample_count(core::sample_count(trajectory));
  summary.set_peak_speed(tool.speed);
  summary.set_peak_acceleration(tool.acceleration);
  summary.set_peak_angular_speed(tool.angular_speed);
  const auto tangential = [](const auto& motion) {
    if (const auto* path = std::get_if<core::PathMotion>(&motion)) return path->timing.peak_acceleration;
    if (const auto* linear = std::get_if<core::LinearMovePlan>(&motion)) return linear->peak_acceleration;
    return 0.0;
  };
  if (const auto* sequence = std::get_if<core::SequenceMotion>(&trajectory)) {
    double peak = 0.0;
    for (const auto& step : sequence->steps) peak = std::max(peak, tangential(step));
    summary.set_peak_tangential_acceleration(peak);
    for (std::size_t i = 0; i < plan.steps.size(); ++i) {
      const auto& s = plan.steps[i];
      auto& out = *response.add_steps();
      out.set_index(static_cast<std::uint32_t>(s.index));
      out.set_last_index(static_cast<std::uint32_t>(s.last_index));
      out.set_kind(s.kind);
      out.set_goal_choice(s.goal_choice);
      for (const auto& c : s.corners) {
        // Collinear lines: no corner, and their blend is the line itself.
        if (c.corner <= core::kSmoothJunction && c.deviation <= 1e-9) continue;
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
      auto& step_summary = *out.mutable_motion();
      step_summary.set_duration_s(s.duration_s);
      step_summary.set_sample_count(s.sample_count);
      step_summary.set_peak_speed(s.tool.speed);
      step_summary.set_peak_acceleration(s.tool.acceleration);
      step_summary.set_peak_angular_speed(s.tool.angular_speed);
      step_summary.set_peak_tangential_acceleration(tangential(sequence->steps[i]));
      if (s.path) {
        const auto* path = std::get_if<core::PathMotion>(&sequence->steps[i]);
        if (path != nullptr) {
          v1::PlanResponse one;
          to_proto(path->path, s.path->achieved, s.path->closed_loop, s.path->geometry, one);
          *out.mutable_segments() = std::move(*one.mutable_segments());
          *out.mutable_frames() = std::move(*one.mutable_frames());
          *out.mutable_closed_loop() = std::move(*one.mutable_closed_loop());
          *out.mutable_warnings() = std::move(*one.mutable_warnings());
        }
      }
      if (with_optimization && (s.optimizers.tangent_scales || s.optimizers.breakpoints || s.optimizers.timing)) {
        to_proto(s.optimizers, *out.mutable_optimization());
      }
    }
  } else {
    summary.set_peak_tangential_acceleration(tangential(trajectory));
  }
}

}  // namespace geotraj::server
