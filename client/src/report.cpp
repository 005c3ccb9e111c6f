#include "report.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include <Eigen/Geometry>

#include "core/planning/corner_blend.hpp"
#include "google/rpc/error_details.pb.h"
#include "google/rpc/status.pb.h"
#include "server/status_codes.hpp"

namespace geotraj::cli {
namespace {

// Fixed-width cells so that columns line up; "-" for an absent value.
// A leading space keeps cells apart even when a value needs more than its width.
std::string num(double v, int width = 12) {
  char buf[64];
  std::snprintf(buf, sizeof buf, " %*.*g", width - 1, 6, v + 0.0);  // + 0.0: -0 prints as 0
  return buf;
}
std::string absent(int width = 12) { return std::string(static_cast<std::size_t>(width - 1), ' ') + "-"; }
std::string cell(const std::string& s, int width) {
  char buf[128];
  std::snprintf(buf, sizeof buf, "%-*s", width, s.c_str());
  return buf;
}
std::string vec(const v1::Vec3& v) { return num(v.x()) + num(v.y()) + num(v.z()); }
std::string vec_or_absent(bool present, const v1::Vec3& v) {
  return present ? vec(v) : absent() + absent() + absent();
}

std::string short_enum(const std::string& name, const std::string& prefix) {
  return name.rfind(prefix, 0) == 0 ? name.substr(prefix.size()) : name;
}

// The most used limit, stretch by stretch, measured on the samples (RobotReport.binding,
// MotionSummary.binding); "binding" only of a limit used whole (it sets the pace there).
void print_binding(const google::protobuf::RepeatedPtrField<v1::BindingStretch>& binding, std::ostream& out) {
  if (binding.empty()) return;
  out << "the most used limit, stretch by stretch (binding: at 100 %):\n";
  for (const auto& b : binding) {
    char row[200];
    const std::string kind = short_enum(v1::BindingKind_Name(b.kind()), "BINDING_KIND_");
    const bool joint = kind.rfind("JOINT_", 0) == 0;  // a Cartesian limit is the tool's
    std::snprintf(row, sizeof row, "  t %8.3f .. %8.3f s  %-24s %-8s peak %.4g of limit %.4g (%.1f%%)%s\n",
                  b.t_start(), b.t_end(), kind.c_str(), joint ? ("joint " + std::to_string(b.joint())).c_str() : "tool",
                  b.value(), b.limit(), 100.0 * b.usage(),
                  b.usage() > 1.001 ? "  above it" : b.usage() >= 0.999 ? "  binding" : "");
    out << row;
  }
}

void print_geometry_row(const std::string& label, const v1::FrenetGeometry& g, std::ostream& out) {
  out << label << num(g.speed()) << (g.has_curvature() ? num(g.curvature()) : absent())
      << (g.has_torsion() ? num(g.torsion()) : absent())
      << (g.has_curvature_derivative() ? num(g.curvature_derivative()) : absent())
      << (g.has_torsion_derivative() ? num(g.torsion_derivative()) : absent()) << "  "
      << vec_or_absent(g.has_tangent(), g.tangent()) << '\n';
}

}  // namespace

void print_table(const v1::ConvertResponse& response, std::ostream& out) {
  out << "parametric constraints d^k p/du^k [m], per side of each key frame\n"
      << "frame  side     k             x           y           z\n";
  for (int i = 0; i < response.frames_size(); ++i) {
    const auto& f = response.frames(i);
    out << cell(std::to_string(i), 7) << cell("position", 11) << ' ' << vec(f.position()) << '\n';
    const auto side = [&](const char* name, const v1::SideConstraints& s) {
      for (int k = 0; k < s.derivatives_size(); ++k) {
        out << cell("", 7) << cell(name, 9) << cell(std::to_string(k + 1), 3) << vec(s.derivatives(k)) << '\n';
      }
    };
    side("approach", f.approach());
    side("leave", f.leave());
  }
}

namespace {

// A sequence's steps: where each lies in time and in the samples, and each path's closed loop.
void print_steps(const v1::PlanResponse& response, std::ostream& out) {
  out << "sequence: " << response.steps_size() << " motions, the robot at rest between them\n"
      << " step  kind            start [s]  duration [s]  first sample   samples   length [m]  closed loop\n";
  for (const auto& s : response.steps()) {
    char buf[200];
    const std::string kind =
        s.last_index() > s.index() ? s.kind() + " " + std::to_string(s.index()) + "-" + std::to_string(s.last_index())
                                   : s.kind();
    std::snprintf(buf, sizeof buf, "%5u  %-12s %12.4f  %12.4f  %12llu  %8llu  %11.6g", s.index(), kind.c_str(),
                  s.start_time_s(), s.duration_s(), static_cast<unsigned long long>(s.first_sample()),
                  static_cast<unsigned long long>(s.sample_count()), s.arc_length());
    out << buf;
    if (s.kind() == "path") out << "  max error" << num(s.closed_loop().max_error(), 1);
    out << '\n';
    if (s.has_motion()) {
      const auto& m = s.motion();
      const auto shown = [](double x) { return std::abs(x) < 1e-12 ? 0.0 : x; };  // rounding, not motion
      std::snprintf(buf, sizeof buf,
                    "       peaks: speed %.4g m/s, acceleration %.4g m/s^2 (tangential %.4g), angular speed %.4g "
                    "rad/s\n",
                    shown(m.peak_speed()), shown(m.peak_acceleration()), shown(m.peak_tangential_acceleration()),
                    shown(m.peak_angular_speed()));
      out << buf;
    }
    if (!s.goal_choice().empty()) out << "       goal: " << s.goal_choice() << '\n';
    for (const auto& c : s.corners()) {
      if (c.corner() <= core::kSmoothJunction) {  // tangent-continuous: the curvature blended
        std::snprintf(buf, sizeof buf,
                      "       junction after step %u: tangent-continuous, its curvature blended (segment %u) within "
                      "%.4g m of the route (tolerance %.4g m), replacing %.4g m before and %.4g m after\n",
                      c.after_step(), c.segment(), c.deviation(), c.tolerance(), c.cut_before(), c.cut_after());
        out << buf;
        continue;
      }
      std::snprintf(buf, sizeof buf,
                    "       corner after step %u: turns %.4g deg, blend (segment %u) within %.4g m of the route "
                    "(tolerance %.4g m), replacing %.4g m before and %.4g m after\n",
                    c.after_step(), c.corner() * 180.0 / 3.14159265358979323846, c.segment(), c.deviation(),
                    c.tolerance(), c.cut_before(), c.cut_after());
      out << buf;
    }
    for (const auto& w : s.warnings()) {
      out << "  WARNING " << short_enum(v1::PlanWarningCode_Name(w.code()), "PLAN_WARNING_CODE_") << ": " << w.message()
          << '\n';
    }
  }
}

}  // namespace

void print_table(const v1::PlanResponse& response, std::ostream& out) {
  if (response.steps_size() > 0 || (response.segments_size() == 0 && response.has_motion())) {
    // A sequence or a move: no path of its own to tabulate.
    if (response.steps_size() > 0) print_steps(response, out);
    print_motion_and_reports(response, out);
    return;
  }
  out << "segments: " << response.segments_size() << ", total arc length" << num(response.arc_length(), 1)
      << " m\n"
      << "  seg  from    to  blend         degree  orders     arc length [m]\n";
  for (const auto& s : response.segments()) {
    std::string orders = std::to_string(s.start_order()) + "/" + std::to_string(s.end_order());
    std::string degree = std::to_string(s.degree());
    if (s.trapezoid_orders_size() > 0) {
      degree = "n=";
      for (int k = 0; k < s.trapezoid_orders_size(); ++k) {
        degree += (k ? "," : "") + std::to_string(s.trapezoid_orders(k));
      }
    }
    // A path of pieces: its exact pieces by number, the transitions between them.
    std::string blend = short_enum(v1::BlendMethod_Name(s.blend()), "BLEND_METHOD_");
    if (s.kind() == v1::SEGMENT_KIND_PIECE) blend = "piece " + std::to_string(s.piece()), degree = "-";
    if (s.kind() == v1::SEGMENT_KIND_TRANSITION) blend = "transition";
    char buf[160];
    std::snprintf(buf, sizeof buf, "%5u %5u %5u  %-12s  %6s  %-7s %17.9g\n", s.index(), s.from_frame(), s.to_frame(),
                  blend.c_str(), degree.c_str(), orders.c_str(), s.arc_length());
    out << buf;
  }
  out << "\nachieved geometry at the key frames, measured on the curve (\"-\": undefined there;\n"
      << "kappa' and tau' in the request's derivative convention)\n"
      << "frame  side        |dp/du|   curvature     torsion      kappa'        tau'  "
      << "   tangent x   tangent y   tangent z\n"
      << "                       [m]       [1/m]       [1/m]\n";
  for (int i = 0; i < response.frames_size(); ++i) {
    const auto& f = response.frames(i);
    if (f.has_approach()) print_geometry_row(cell(std::to_string(i), 7) + cell("approach", 8), f.approach(), out);
    if (f.has_leave()) print_geometry_row(cell(std::to_string(i), 7) + cell("leave", 8), f.leave(), out);
  }
  const auto& loop = response.closed_loop();
  out << "\nclosed loop: max error " << num(loop.max_error(), 1)
      << (loop.worst_field().empty() ? std::string() : " at " + loop.worst_field()) << '\n';
  out << "\ngeometry between the frames, measured on the curve\n"
      << "  seg  peak kappa        at u    peak tau        at u  min |dp/du|        at u     turning\n"
      << "            [1/m]                  [1/m]                     [m]                   [rad]\n";
  for (const auto& s : response.segments()) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%5u", s.index());
    out << buf << num(s.peak_curvature().value()) << num(s.peak_curvature().u()) << num(s.peak_torsion().value())
        << num(s.peak_torsion().u()) << num(s.min_speed().value()) << num(s.min_speed().u()) << num(s.turning())
        << '\n';
  }
  for (const auto& w : response.warnings()) {
    out << "WARNING " << short_enum(v1::PlanWarningCode_Name(w.code()), "PLAN_WARNING_CODE_") << ": " << w.message()
        << '\n';
  }
  print_motion_and_reports(response, out);
}

void print_motion_and_reports(const v1::PlanResponse& response, std::ostream& out) {
  if (response.has_motion()) {
    const auto& m = response.motion();
    out << "\nmotion: duration" << num(m.duration_s(), 1) << " s, peak speed" << num(m.peak_speed(), 1)
        << " m/s, peak acceleration" << num(m.peak_acceleration(), 1) << " m/s^2 (tangential"
        << num(m.peak_tangential_acceleration(), 1) << "), peak angular speed" << num(m.peak_angular_speed(), 1)
        << " rad/s, " << m.sample_count() << " samples\n";
    print_binding(m.binding(), out);
  }
  if (response.has_optimization()) print_table(response.optimization(), out);
  if (response.has_robot()) print_table(response.robot(), out);
}

namespace {

template <class Report>
void print_optimizer(const char* what, const char* unit, const Report& r, std::ostream& out) {
  char row[240];
  std::snprintf(row, sizeof row, "%-15s %-16s objective %.6g -> %.6g%s%s, %u iterations, %.3f s%s%s\n", what,
                short_enum(v1::OptimizerStatus_Name(r.status()), "OPTIMIZER_STATUS_").c_str(), r.objective_before(),
                r.objective_after(), *unit ? " " : "", unit, r.iterations(), r.seconds(),
                r.message().empty() ? "" : ": ", r.message().c_str());
  out << row;
}

}  // namespace

void print_table(const v1::OptimizationReport& report, std::ostream& out) {
  out << "\noptimisation:\n";
  if (report.has_tangent_scales()) {
    const auto& t = report.tangent_scales();
    print_optimizer("tangent scales", "", t, out);
    out << "  chosen scales [m]:";
    for (double x : t.tangent_scales()) out << ' ' << num(x, 1);
    if (t.length_weight() > 0.0) out << "; length weight" << num(t.length_weight(), 1) << " 1/m^2";
    out << '\n';
  }
  if (report.has_breakpoints()) {
    const auto& b = report.breakpoints();
    print_optimizer("breakpoints", "", b, out);
    for (const auto& seg : b.breakpoints()) {
      const std::pair<const char*, const google::protobuf::RepeatedField<double>*> axes[] = {
          {"all", &seg.all()}, {"x", &seg.x()}, {"y", &seg.y()}, {"z", &seg.z()}};
      for (const auto& [name, values] : axes) {
        if (values->empty()) continue;
        out << "  segment " << seg.segment() << ' ' << name << ':';
        for (double x : *values) out << ' ' << num(x, 1);
        out << '\n';
      }
    }
  }
  if (report.has_timing()) {
    const auto& t = report.timing();
    print_optimizer("timing", "s", t, out);
    if (t.check_rate_hz() > 0.0) {
      char row[240];
      std::snprintf(row, sizeof row,
                    "  limits checked at %g Hz: worst %.9g of a limit after %u re-solves; duration grid error %.3g s\n",
                    t.check_rate_hz(), t.worst_limit_usage(), t.refinements(), t.duration_grid_error_s());
      out << row;
    }
    if (t.binding_size() > 0) out << "  the most used limit, stretch by stretch (binding: at 100 %):\n";
    for (const auto& b : t.binding()) {
      char row[240];
      std::snprintf(row, sizeof row, "  s %7.4f .. %7.4f m  t %7.3f .. %7.3f s  %-34s joint %u  %.4g of %.4g%s\n",
                    b.s_start(), b.s_end(), b.t_start(), b.t_end(),
                    short_enum(v1::BindingKind_Name(b.kind()), "BINDING_KIND_").c_str(), b.joint(), b.value(),
                    b.limit(), b.usage() >= 0.999 ? "  binding" : "");
      out << row;
    }
  }
}

namespace {

std::string event_text(const v1::LimitEvent& e) {
  char buf[200];
  std::snprintf(buf, sizeof buf, "%-12s joint %u  t = %.4f s (sample %llu)  value %.6g  limit %.6g  margin %.6g",
                short_enum(v1::LimitKind_Name(e.kind()), "LIMIT_KIND_").c_str(), e.joint(), e.t(),
                static_cast<unsigned long long>(e.sample()), e.value(), e.limit(), e.margin());
  return buf;
}

}  // namespace

void print_table(const v1::RobotReport& robot, std::ostream& out) {
  out << "\nrobot " << robot.name() << ": " << robot.samples() << " samples, "
      << (robot.feasible() ? "within every limit" : "LIMITS BROKEN") << '\n'
      << "joint     min q       max q    q margin   peak |qd|  vel usage  peak |qdd|  acc usage";
  const bool torques = std::any_of(robot.joints().begin(), robot.joints().end(),
                                   [](const v1::JointReport& j) { return j.has_peak_torque(); });
  out << (torques ? " peak |tau|  tau usage\n" : "\n");
  for (const auto& j : robot.joints()) {
    char buf[200];
    std::snprintf(buf, sizeof buf, "%5u %11.5f %11.5f %11.5f %11.5f %9.1f%% %11.5f %9.1f%%", j.joint(),
                  j.min_position(), j.max_position(), j.position_margin(), j.peak_velocity(),
                  100.0 * j.velocity_usage(), j.peak_acceleration(), 100.0 * j.acceleration_usage());
    out << buf;
    if (torques && j.has_torque_usage()) {
      std::snprintf(buf, sizeof buf, " %10.4f %9.1f%%", j.peak_torque(), 100.0 * j.torque_usage());
      out << buf;
    } else if (torques) {
      std::snprintf(buf, sizeof buf, " %10.4f %10s", j.peak_torque(), "-");
      out << buf;
    }
    out << '\n';
  }
  // Where the limits come from, for joints whose limits are not all the model's own.
  for (const auto& j : robot.joints()) {
    const auto& from = j.limit_sources();
    const std::string own = "the model's";
    if (from.velocity() == own && from.acceleration() == own && (from.jerk().empty() || from.jerk() == own) &&
        (from.torque().empty() || from.torque() == own))
      continue;
    out << "joint " << j.joint() << " limits from: velocity " << from.velocity() << "; acceleration "
        << from.acceleration();
    if (!from.jerk().empty()) out << "; jerk " << from.jerk();
    if (!from.torque().empty()) out << "; torque " << from.torque();
    out << '\n';
  }
  out << "tightest position:     " << event_text(robot.tightest_position()) << '\n'
      << "tightest velocity:     " << event_text(robot.tightest_velocity()) << '\n'
      << "tightest acceleration: " << event_text(robot.tightest_acceleration()) << '\n';
  char buf[240];
  std::snprintf(buf, sizeof buf,
                "IK residuals: max %.3g m, %.3g rad; joint-interpolation midpoint deviation: max %.3g m at t = %.4f s\n"
                "manipulability: min %.4g at t = %.4f s\n",
                robot.max_ik_position_error(), robot.max_ik_orientation_error(), robot.max_midpoint_deviation(),
                robot.max_midpoint_deviation_t(), robot.min_manipulability(), robot.min_manipulability_t());
  out << buf;
  for (const auto& v : robot.violations()) out << "VIOLATION " << event_text(v) << '\n';
  if (robot.has_default_jerk()) out << "default jerk: " << robot.default_jerk().message() << '\n';
  print_binding(robot.binding(), out);
}

void print_table(const v1::ListRobotsResponse& robots, std::ostream& out) {
  const auto limits = [](const v1::JointLimits& lim, v1::JointType type) {
    char buf[96];
    if (type == v1::JOINT_TYPE_CONTINUOUS) {
      std::snprintf(buf, sizeof buf, "%9s %9s %7.4f", "-", "-", lim.max_velocity());
    } else {
      std::snprintf(buf, sizeof buf, "%9.4f %9.4f %7.4f", lim.min_position(), lim.max_position(), lim.max_velocity());
    }
    std::string text = buf;
    if (lim.max_acceleration() > 0.0) {
      std::snprintf(buf, sizeof buf, " %8.4f", lim.max_acceleration());
      text += buf;
    } else {
      text += "  unknown";  // a URDF as shipped: kinematics only until a limit is given
    }
    return text;
  };
  const auto kind = [](v1::JointType type) { return short_enum(v1::JointType_Name(type), "JOINT_TYPE_"); };
  // The name column as wide as the longest name (at least the header's): names are whole.
  const auto width = [](const auto& joints, int least) {
    int w = least;
    for (const auto& j : joints) w = std::max(w, static_cast<int>(std::min<std::size_t>(j.name().size(), 64)));
    return w;
  };
  for (const auto& m : robots.robots()) {
    if (m.links_size() > 0) {  // a DH table
      const int w = width(m.links(), 14);
      out << m.name() << "  (" << m.links_size() << " joints, "
          << short_enum(v1::DhConvention_Name(m.dh_convention()), "DH_CONVENTION_") << " DH)\n  " << m.description()
          << "\n  joint  " << std::string("name") + std::string(static_cast<std::size_t>(w - 3), ' ')
          << "type          a [m]  alpha [rad]       d [m]  theta [rad]     min q     max q  max qd  max qdd\n";
      for (int i = 0; i < m.links_size(); ++i) {
        const auto& l = m.links(i);
        char buf[400];
        std::snprintf(buf, sizeof buf, "  %5d  %-*.*s %-10s %9.5f %12.6f %11.5f %12.6f ", i, w, w, l.name().c_str(),
                      kind(l.joint_type()).c_str(), l.a(), l.alpha(), l.d(), l.theta() + l.offset());
        out << buf << (i < m.limits_size() ? limits(m.limits(i), l.joint_type()) : std::string()) << '\n';
      }
      continue;
    }
    // A general chain (URDF): each joint's origin (position, roll-pitch-yaw) and axis.
    const int w = width(m.joints(), 17);
    out << m.name() << "  (" << m.joints_size() << " joints, general chain)\n  " << m.description() << "\n  joint  "
        << std::string("name") + std::string(static_cast<std::size_t>(w - 3), ' ')
        << "type        origin x     y [m]     z [m]  roll  pitch   yaw [rad]   axis x     y     z     min q     max q  "
           "max qd  max qdd\n";
    for (int i = 0; i < m.joints_size(); ++i) {
      const auto& j = m.joints(i);
      const auto& o = j.origin().orientation();
      const Eigen::Matrix3d R = Eigen::Quaterniond(o.w(), o.x(), o.y(), o.z()).normalized().toRotationMatrix();
      // Fixed-axis roll, pitch, yaw (URDF's rpy): R = Rz(yaw) Ry(pitch) Rx(roll).
      const auto clean = [](double x) { return std::abs(x) < 5e-13 ? 0.0 : x; };  // no "-0.000"
      const double pitch = clean(std::asin(std::clamp(-R(2, 0), -1.0, 1.0)));
      const double roll = clean(std::atan2(R(2, 1), R(2, 2))), yaw = clean(std::atan2(R(1, 0), R(0, 0)));
      const auto& p = j.origin().position();
      char buf[400];
      std::snprintf(buf, sizeof buf, "  %5d  %-*.*s %-10s %9.4f %9.4f %9.4f %6.3f %6.3f %6.3f   %6.3f %5.3f %5.3f ", i, w,
                    w, j.name().c_str(), kind(j.joint_type()).c_str(), p.x(), p.y(), p.z(), roll, pitch, yaw, j.axis().x(),
                    j.axis().y(), j.axis().z());
      out << buf << (i < m.limits_size() ? limits(m.limits(i), j.joint_type()) : std::string()) << '\n';
    }
  }
}

void print_table(const v1::PathProfile& profile, std::ostream& out) {
  out << "path profile: " << profile.points_size() << " points, arc length" << num(profile.arc_length(), 1)
      << " m; derivatives per metre of arc (\"-\": undefined there)\n"
      << "           u        s [m]  seg        x [m]        y [m]        z [m]   curvature     torsion"
      << "   dkappa/ds     dtau/ds  speed |p'|\n";
  for (const auto& p : profile.points()) {
    char seg[16];
    std::snprintf(seg, sizeof seg, "%5u", p.segment());
    out << num(p.u()) << num(p.s(), 13) << seg << num(p.position().x(), 13) << num(p.position().y(), 13)
        << num(p.position().z(), 13) << (p.has_curvature() ? num(p.curvature()) : absent())
        << (p.has_torsion() ? num(p.torsion()) : absent())
        << (p.has_curvature_derivative() ? num(p.curvature_derivative()) : absent())
        << (p.has_torsion_derivative() ? num(p.torsion_derivative()) : absent()) << num(p.speed()) << '\n';
  }
}

namespace {

void print_pose(const char* label, const v1::Pose& pose, std::ostream& out) {
  const auto& p = pose.position();
  const auto& q = pose.orientation();
  char buf[240];
  std::snprintf(buf, sizeof buf, "%s position (%.6f, %.6f, %.6f) m, orientation (w, x, y, z) (%.6f, %.6f, %.6f, %.6f)\n",
                label, p.x(), p.y(), p.z(), q.w(), q.x(), q.y(), q.z());
  out << buf;
}

void print_joints(const google::protobuf::RepeatedField<double>& joints, std::ostream& out) {
  char buf[32];
  for (double q : joints) {
    std::snprintf(buf, sizeof buf, " %10.6f", q);
    out << buf;
  }
}

}  // namespace

void print_table(const v1::ForwardKinematicsResponse& fk, std::ostream& out) {
  print_pose("tool:", fk.pose(), out);
  char buf[200];
  std::snprintf(buf, sizeof buf, "manipulability %.6g, singular values %.6g to %.6g; joints %s their limits\n",
                fk.manipulability(), fk.min_singular_value(), fk.max_singular_value(),
                fk.within_limits() ? "within" : "NOT within");
  out << buf << "joint   axis origin [m]                          axis direction\n";
  for (int i = 0; i < fk.axes_size(); ++i) {
    const auto& o = fk.axes(i).origin();
    const auto& d = fk.axes(i).direction();
    std::snprintf(buf, sizeof buf, "%5d   (%9.6f, %9.6f, %9.6f)   (%9.6f, %9.6f, %9.6f)\n", i, o.x(), o.y(), o.z(),
                  d.x(), d.y(), d.z());
    out << buf;
  }
  const int n = fk.axes_size();
  out << "Jacobian (rows vx vy vz [m/s] wx wy wz [rad/s] per unit joint speed, columns joint 0 to " << n - 1 << "):\n";
  for (int r = 0; r < 6 && n > 0; ++r) {
    for (int c = 0; c < n; ++c) {
      std::snprintf(buf, sizeof buf, " %10.6f", fk.jacobian(r * n + c));
      out << buf;
    }
    out << '\n';
  }
}

void print_table(const v1::InverseKinematicsResponse& ik, std::ostream& out) {
  char buf[200];
  if (!ik.reachable()) {
    const auto& c = ik.closest();
    std::snprintf(buf, sizeof buf,
                  "out of reach (%u attempts, %u iterations): the closest pose is %.6g m and %.6g rad from the target\n",
                  ik.attempts(), ik.iterations(), c.position_error(), c.orientation_error());
    out << buf;
    print_pose("closest:", c.pose(), out);
    out << "joints [rad or m]:";
    print_joints(c.joints(), out);
    out << '\n';
    return;
  }
  std::snprintf(buf, sizeof buf, "%d solution%s (%u attempts, %u iterations), nearest the seed first\n",
                ik.solutions_size(), ik.solutions_size() == 1 ? "" : "s", ik.attempts(), ik.iterations());
  out << buf << "   #  from seed  manipul.   joints 0.. [rad or m]\n";
  for (int k = 0; k < ik.solutions_size(); ++k) {
    const auto& s = ik.solutions(k);
    std::snprintf(buf, sizeof buf, "%4d %10.4f %9.5f  ", k, s.distance_from_seed(), s.manipulability());
    out << buf;
    print_joints(s.joints(), out);
    out << '\n';
  }
}

void print_sample_csv_header(const v1::Sample& first, bool sequence, std::ostream& out) {
  out << "t,u,s,segment,x,y,z,qw,qx,qy,qz,vx,vy,vz,ax,ay,az,speed,wx,wy,wz";
  if (sequence) out << ",step";
  for (const char* name : {"q", "qd", "qdd"}) {  // joint 0 at the base
    for (int j = 0; j < first.joints_size(); ++j) out << ',' << name << j;
  }
  for (int j = 0; j < first.joint_torques_size(); ++j) out << ",tau" << j;  // a model with mass properties
}

void print_sample_csv(const v1::Sample& s, bool sequence, std::ostream& out) {
  const auto& p = s.position();
  const auto& q = s.orientation();
  const auto& v = s.velocity();
  const auto& a = s.acceleration();
  const auto& w = s.angular_velocity();
  char line[512];
  std::snprintf(line, sizeof line,
                "%.9g,%.17g,%.17g,%u,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,"
                "%.17g,%.17g,%.17g,%.17g,%.17g",
                s.t(), s.u(), s.s(), s.segment(), p.x(), p.y(), p.z(), q.w(), q.x(), q.y(), q.z(), v.x(), v.y(), v.z(),
                a.x(), a.y(), a.z(), s.speed(), w.x(), w.y(), w.z());
  out << line;
  if (sequence) out << ',' << s.step();
  for (const auto* values : {&s.joints(), &s.joint_velocities(), &s.joint_accelerations(), &s.joint_torques()}) {
    for (double x : *values) {
      std::snprintf(line, sizeof line, ",%.17g", x);
      out << line;
    }
  }
}

void print_error(const grpc::Status& status, std::ostream& err) {
  err << "geotraj: " << server::status_code_name(status.error_code()) << ": " << status.error_message() << '\n';
  google::rpc::Status details;
  if (status.error_details().empty() || !details.ParseFromString(status.error_details())) return;
  for (const auto& any : details.details()) {
    google::rpc::BadRequest bad_request;
    google::rpc::PreconditionFailure failure;
    if (any.UnpackTo(&bad_request)) {
      for (const auto& v : bad_request.field_violations()) err << "  " << v.field() << ": " << v.description() << '\n';
    } else if (any.UnpackTo(&failure)) {
      for (const auto& v : failure.violations()) {
        err << "  " << short_enum(v.type(), "LIMIT_KIND_") << ", " << v.subject() << ": " << v.description() << '\n';
      }
    }
  }
}

}  // namespace geotraj::cli
