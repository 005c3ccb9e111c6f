// Paths on the wire (convert.hpp): key frames read and checked, ConvertConstraints' and
// AnalyzePath's answers, the geometry part of PlanTrajectory's.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <set>
#include <string>
#include <type_traits>
#include <utility>
#include <variant>

#include "core/format.hpp"
#include "server/wire/convert.hpp"
#include "server/wire/wire_detail.hpp"

namespace geotraj::server {

using namespace wire_detail;

namespace {

using wire_detail::to_core;  // beside the overloads for key frames and paths below

std::string at_frame(std::size_t i) { return "path.frames[" + std::to_string(i) + "]"; }

// One key frame at `at` (core's field: `core_at`); `held`: ORIENTATION_MODE_FIXED may give
// the orientation held (a path of pieces' start).
void check_frame(WireCheck& check, const v1::KeyFrame& frame, const std::string& at, const std::string& core_at,
                 bool held = false) {
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
  const bool fixed = frame.orientation_mode() == v1::ORIENTATION_MODE_FIXED ||
                     frame.orientation_mode() == v1::ORIENTATION_MODE_UNSPECIFIED;
  if (!custom && !(held && fixed) && frame.has_orientation() && v1::OrientationMode_IsValid(frame.orientation_mode())) {
    check.add(at + ".orientation", "is only used with orientationMode ORIENTATION_MODE_CUSTOM (and "
                                   "ORIENTATION_MODE_FIXED on the first frame: the orientation held); "
                                   "orientationMode is " +
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
  for (int i = 0; i < path.frames_size(); ++i) {
    const auto k = static_cast<std::size_t>(i);
    check_frame(check, path.frames(i), at_frame(k), "frames[" + std::to_string(k) + "]", /*held=*/i == 0);
  }
  if (path.has_start()) check_frame(check, path.start(), "path.start", "start", /*held=*/true);
  if (path.pieces_size() > 0 && !path.has_start())
    check.add("path.start", "is required with pieces: the frame the first piece starts from");
  for (int i = 0; i < path.pieces_size(); ++i) {
    const std::string core_at = "pieces[" + std::to_string(i) + "]";
    const auto& piece = path.pieces(i);
    if (piece.shape_case() == v1::PathPiece::SHAPE_NOT_SET)
      check.add("path." + core_at, "give its shape: one of line, arc, helix, clothoid, profile, to");
    if (piece.has_to()) check_frame(check, piece.to(), "path." + core_at + ".to", core_at + ".to");
  }
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
  if (p.has_start()) spec.start = to_core(p.start());
  spec.pieces.reserve(static_cast<std::size_t>(p.pieces_size()));
  for (const auto& in : p.pieces()) {
    core::PathPiece piece;
    piece.length_m = in.length_m();
    switch (in.shape_case()) {
      case v1::PathPiece::kArc:
        piece.shape = core::PieceShape::kArc;
        piece.radius = in.arc().radius();
        break;
      case v1::PathPiece::kHelix:
        piece.shape = core::PieceShape::kHelix;
        piece.radius = in.helix().radius();
        piece.pitch = in.helix().pitch();
        break;
      case v1::PathPiece::kClothoid:
        piece.shape = core::PieceShape::kClothoid;
        piece.end_curvature = in.clothoid().end_curvature();
        break;
      case v1::PathPiece::kProfile:
        piece.shape = core::PieceShape::kProfile;
        piece.curvature.assign(in.profile().curvature().begin(), in.profile().curvature().end());
        piece.torsion.assign(in.profile().torsion().begin(), in.profile().torsion().end());
        break;
      case v1::PathPiece::kTo:
        piece.shape = core::PieceShape::kTo;
        piece.to = to_core(in.to());
        break;
      default:  // line, or no shape (refused by check_path)
        piece.shape = core::PieceShape::kLine;
        break;
    }
    spec.pieces.push_back(std::move(piece));
  }
  if (p.has_transition_tolerance()) spec.transition_tolerance = p.transition_tolerance();
  switch (p.unspecified()) {
    case v1::UNSPECIFIED_CONSTRAINTS_THESIS_ZEROS: spec.unspecified = core::UnspecifiedConstraints::kThesisZeros; break;
    case v1::UNSPECIFIED_CONSTRAINTS_LOWEST_DEGREE: spec.unspecified = core::UnspecifiedConstraints::kLowestDegree; break;
    default: spec.unspecified = core::UnspecifiedConstraints::kSmoothest; break;  // SMOOTHEST and UNSPECIFIED
  }
  return spec;
}

// The path as given, what could not be read named from the path (the wire checks' field
// paths less their root "path."). A path of more than `max_frames` key frames is refused
// before any of it is read.
planner::PathInput read_path(const v1::PathSpec& path, int max_frames) {
  planner::PathInput in;
  if (path.frames_size() > max_frames) {
    in.read = false;
    in.violations.push_back({"frames", "has " + std::to_string(path.frames_size()) +
                                           " key frames; this server accepts at most " + std::to_string(max_frames) +
                                           " (geotrajd --max-frames)"});
    return in;
  }
  if (path.pieces_size() > max_frames) {
    in.read = false;
    in.violations.push_back({"pieces", "has " + std::to_string(path.pieces_size()) +
                                           " pieces; this server accepts at most " + std::to_string(max_frames) +
                                           " (geotrajd --max-frames)"});
    return in;
  }
  WireCheck check;
  check_path(check, path);
  in.spec = to_core(path);
  static constexpr std::string_view root = "path.";
  for (auto& v : check.violations) in.violations.push_back({v.field.substr(root.size()), std::move(v.description)});
  in.unchecked = std::move(check.suppressed);
  return in;
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

void wire_detail::check_enum(WireCheck& check, const std::string& field, int value,
                             const google::protobuf::EnumDescriptor* descriptor) {
  if (descriptor->FindValueByNumber(value) != nullptr) return;
  std::string names;
  for (int i = 0; i < descriptor->value_count(); ++i) {
    if (!names.empty()) names += ", ";
    names += descriptor->value(i)->name();
  }
  check.add(field, "unknown value " + std::to_string(value) + "; use one of " + names);
}

std::optional<planner::PathInput> path_input(const v1::ConvertRequest& request, const ServiceLimits& limits) {
  if (!request.has_path()) return std::nullopt;
  return path_input(request.path(), limits);
}

planner::PathInput wire_detail::path_input(const v1::PathSpec& path, const ServiceLimits& limits) {
  return read_path(path, limits.max_frames);
}

void wire_detail::check_request_numbers(const v1::PlanRequest& request, const ServiceLimits& limits,
                                        WireCheck& check) {
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

using wire_detail::set;  // beside the overload for extrema below

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
          } else if constexpr (std::is_same_v<T, core::TrapezoidSegment>) {
            for (const auto& axis : seg.axes) s->add_trapezoid_orders(static_cast<std::uint32_t>(axis.n));
          }
        },
        path.segments[i]);
    if (i < path.origins.size()) {
      static constexpr v1::SegmentKind kKind[] = {v1::SEGMENT_KIND_BLEND, v1::SEGMENT_KIND_PIECE,
                                                  v1::SEGMENT_KIND_TRANSITION};
      s->set_kind(kKind[static_cast<int>(path.origins[i].kind)]);
      s->set_piece(static_cast<std::uint32_t>(path.origins[i].piece));
    } else {
      s->set_kind(v1::SEGMENT_KIND_BLEND);
    }
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

}  // namespace geotraj::server
