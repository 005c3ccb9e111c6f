#include "test_support.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <sstream>

namespace geotraj::test {

core::PathSpec make_spec(std::vector<core::KeyFrame> frames, core::DerivativeConvention convention,
                         core::BlendMethod blend, bool closed, core::UnspecifiedConstraints reading) {
  core::PathSpec spec;
  for (auto& f : frames) f.tangent_scale = f.tangent_scale.value_or(1.0);
  spec.frames = std::move(frames);
  spec.unspecified = reading;
  spec.convention = convention;
  spec.blend = blend;
  spec.closed = closed;
  return spec;
}

core::Path build_or_fail(const core::PathSpec& spec) {
  auto path = core::build_path(spec);
  if (!path) {
    std::string all;
    for (const auto& v : path.error()) all += "\n  " + v.field + ": " + v.description;
    ADD_FAILURE() << "build_path rejected the spec:" << all << "\nspec: " << describe(spec);
    return {};
  }
  return std::move(*path);
}

namespace {

std::string num(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

std::string vec(const Vector3d& v) { return "{\"x\": " + num(v.x()) + ", \"y\": " + num(v.y()) + ", \"z\": " + num(v.z()) + "}"; }

std::string plain(const Vector3d& v) { return "(" + num(v.x()) + ", " + num(v.y()) + ", " + num(v.z()) + ")"; }

}  // namespace

::testing::AssertionResult VecNear(const Vector3d& actual, const Vector3d& expected, double tol) {
  const Vector3d diff = (actual - expected).cwiseAbs();
  Eigen::Index worst = 0;
  const double err = diff.maxCoeff(&worst);
  if (err <= tol) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "actual " << plain(actual) << " differs from expected " << plain(expected)
                                       << " by " << num(err) << " in component " << "xyz"[worst]
                                       << " (tolerance " << num(tol) << ")";
}

Printed::Printed(const char* t) : text(t) {
  char* end = nullptr;
  value = std::strtod(t, &end);
  const char* dot = std::strchr(t, '.');
  const int decimals = dot ? static_cast<int>(end - dot - 1) : 0;
  tol = 0.5 * std::pow(10.0, -decimals);
}

::testing::AssertionResult MatchesPrinted(const Vector3d& actual, const PrintedVec& printed, double min_tol) {
  ::testing::AssertionResult result = ::testing::AssertionSuccess();
  bool ok = true;
  std::ostringstream why;
  for (int i = 0; i < 3; ++i) {
    const double tol = std::max(printed[i].tol, min_tol);
    const double err = std::abs(actual(i) - printed[i].value);
    if (!(err <= tol)) {
      ok = false;
      why << "\n  " << "xyz"[i] << ": geotraj " << num(actual(i)) << ", thesis prints " << printed[i].text
          << " (difference " << num(err) << ", tolerance " << num(tol) << ")";
    }
  }
  if (ok) return result;
  return ::testing::AssertionFailure() << "geotraj " << plain(actual) << " does not match the printed ("
                                       << printed[0].text << ", " << printed[1].text << ", " << printed[2].text
                                       << ")" << why.str();
}

std::string describe(const core::PathSpec& spec) {
  std::ostringstream os;
  os << "{\"frames\": [";
  for (std::size_t i = 0; i < spec.frames.size(); ++i) {
    const auto& f = spec.frames[i];
    os << (i ? ",\n  " : "\n  ") << "{\"position\": " << vec(f.p_W) << ", \"tangent\": " << vec(f.T_W);
    if (f.N_W) os << ", \"normal\": " << vec(*f.N_W);
    if (f.B_W) os << ", \"binormal\": " << vec(*f.B_W);
    if (f.kappa) os << ", \"curvature\": " << num(*f.kappa);
    if (f.kappa_d) os << ", \"curvatureDerivative\": " << num(*f.kappa_d);
    if (f.tau) os << ", \"torsion\": " << num(*f.tau);
    if (f.tau_d) os << ", \"torsionDerivative\": " << num(*f.tau_d);
    if (f.tangent_scale) os << ", \"tangentScale\": " << num(*f.tangent_scale);
    if (f.cusp) os << ", \"cusp\": true";
    if (f.inflection) os << ", \"inflection\": true";
    os << "}";
  }
  os << "],\n \"derivativeConvention\": \""
     << (spec.convention == core::DerivativeConvention::kPerArcLength ? "PER_ARC_LENGTH" : "PER_PARAMETER")
     << "\", \"blend\": \"" << (spec.blend == core::BlendMethod::kPolynomial ? "POLYNOMIAL" : "TRAPEZOIDAL") << "\"";
  if (spec.closed) os << ", \"closed\": true";
  if (!spec.breakpoints.empty()) {
    os << ",\n \"breakpoints\": [";
    const auto list = [&](const char* name, const std::vector<double>& u) {
      if (u.empty()) return;
      os << ", \"" << name << "\": [";
      for (std::size_t k = 0; k < u.size(); ++k) os << (k ? ", " : "") << num(u[k]);
      os << "]";
    };
    for (std::size_t i = 0; i < spec.breakpoints.size(); ++i) {
      const auto& bp = spec.breakpoints[i];
      os << (i ? ", " : "") << "{\"segment\": " << bp.segment;
      list("all", bp.all);
      list("x", bp.x);
      list("y", bp.y);
      list("z", bp.z);
      os << "}";
    }
    os << "]";
  }
  os << "}";
  return os.str();
}

int property_case_count(int fallback) {
  const char* env = std::getenv("GEOTRAJ_PROPERTY_CASES");
  if (!env || !*env) return fallback;
  char* end = nullptr;
  const long n = std::strtol(env, &end, 10);
  if (*end != '\0' || n < 1) {
    ADD_FAILURE() << "GEOTRAJ_PROPERTY_CASES must be a positive integer, got \"" << env << "\"";
    return fallback;
  }
  return static_cast<int>(n);
}

std::string listed(const core::Violations& v) {
  std::string out;
  for (const auto& x : v) out += "  " + x.field + ": " + x.description + "\n";
  return out;
}

bool names(const core::Violations& v, const std::string& field) {
  return std::any_of(v.begin(), v.end(), [&](const auto& x) { return x.field == field; });
}

}  // namespace geotraj::test
