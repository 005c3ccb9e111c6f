// Helpers shared by the core tests: a fluent key-frame builder, vector assertions that
// print both sides, "as printed" numbers whose tolerance is their printed precision, and a
// replayable text form of a PathSpec for failing random cases.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <gtest/gtest.h>

#include "core/error.hpp"
#include "core/geometry/key_frame.hpp"
#include "core/geometry/path.hpp"

namespace geotraj::test {

using Eigen::Vector3d;

/// Builds a core::KeyFrame in one expression:
///   Frame({1, 1, 1}, {0, 0.707, 0.707}).normal({-1, 0, 0}).curvature(3).torsion(-10)
class Frame {
 public:
  Frame(const Vector3d& p_W, const Vector3d& T_W) {
    f_.p_W = p_W;
    f_.T_W = T_W;
  }
  Frame& normal(const Vector3d& N_W) {
    f_.N_W = N_W;
    return *this;
  }
  Frame& binormal(const Vector3d& B_W) {
    f_.B_W = B_W;
    return *this;
  }
  Frame& curvature(double kappa) {
    f_.kappa = kappa;
    return *this;
  }
  Frame& curvature_derivative(double kappa_d) {
    f_.kappa_d = kappa_d;
    return *this;
  }
  Frame& torsion(double tau) {
    f_.tau = tau;
    return *this;
  }
  Frame& torsion_derivative(double tau_d) {
    f_.tau_d = tau_d;
    return *this;
  }
  Frame& scale(double tangent_scale) {
    f_.tangent_scale = tangent_scale;
    return *this;
  }
  Frame& cusp() {
    f_.cusp = true;
    return *this;
  }
  Frame& inflection() {
    f_.inflection = true;
    return *this;
  }
  operator core::KeyFrame() const { return f_; }  // NOLINT: implicit on purpose

 private:
  core::KeyFrame f_;
};

/// A PathSpec from frames and the usual options. The unit tests of the conversion and the
/// blends are written for the thesis's Chapter 5 and Appendix B cases: lowest-degree segments
/// and a tangent scale of 1 where a frame gives none (the thesis's |dp/du| = 1). The readings
/// and the chord-length default have tests of their own (readings_test.cpp).
core::PathSpec make_spec(std::vector<core::KeyFrame> frames,
                         core::DerivativeConvention convention = core::DerivativeConvention::kPerArcLength,
                         core::BlendMethod blend = core::BlendMethod::kPolynomial, bool closed = false,
                         core::UnspecifiedConstraints reading = core::UnspecifiedConstraints::kLowestDegree);

/// build_path that fails the test (with every violation printed) when the spec is invalid.
core::Path build_or_fail(const core::PathSpec& spec);

/// |actual - expected|_inf <= tol, printing both vectors and the worst component.
::testing::AssertionResult VecNear(const Vector3d& actual, const Vector3d& expected, double tol);

/// A number as the thesis prints it: the value and half a unit of its last printed digit
/// ("7.0679" -> 7.0679 +- 0.00005, "-.707" -> -0.707 +- 0.0005, "-3.0" -> -3 +- 0.05).
struct Printed {
  Printed(const char* text);  // NOLINT: implicit, so tables read like the thesis
  Printed(std::string label, double v, double t) : text(std::move(label)), value(v), tol(t) {}
  std::string text;
  double value;
  double tol;
};

/// The z of the thesis's planar examples (Tables 5.2-5.5, 5.12-5.15): not printed, exactly 0.
inline const Printed kPlanarZ{"(planar) 0", 0.0, 0.0};

/// A printed row of three components (x, y, z).
using PrintedVec = std::array<Printed, 3>;

/// Each component of `actual` within the printed precision of `printed` (or `min_tol`,
/// whichever is larger), reporting the component and both numbers on failure.
::testing::AssertionResult MatchesPrinted(const Vector3d& actual, const PrintedVec& printed, double min_tol = 0.0);

/// A JSON-like, replayable description (17 significant digits) of a spec.
std::string describe(const core::PathSpec& spec);

/// Deterministic seed for random tests, and the number of random cases
/// (environment variable GEOTRAJ_PROPERTY_CASES, else `fallback`).
/// The violations one per line ("  field: description"), for failure messages.
std::string listed(const core::Violations& v);
/// Whether some violation names exactly `field`.
bool names(const core::Violations& v, const std::string& field);

inline constexpr std::uint64_t kPropertySeed = 20240611;
int property_case_count(int fallback);

}  // namespace geotraj::test
