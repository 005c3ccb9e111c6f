// Golden: thesis Appendix B.3, Table B.2, the parametric constraints of Table B.1.
// Tolerance = half a unit of the last printed digit. See golden_support.hpp for the tangent
// scale |printed T| that reproduces the thesis's 0.707 arithmetic.
#include <gtest/gtest.h>

#include "golden_support.hpp"

namespace geotraj::test {
namespace {

// Table B.1. Frames 1 and 3 print kappa = kappa' = tau = tau' = 0; geotraj rejects the
// derivatives and torsion where kappa = 0 (thesis footnote 5), so only kappa = 0 is given.
// Frame 2 gives kappa' = tau' = 0, so both its sides fix derivatives up to the 4th order.
core::PathSpec tableB_1() {
  return make_spec({
      Frame({0, 0, 0}, {1, 0, 0}).normal({0, 1, 0}).binormal({0, 0, 1}).curvature(0),
      Frame({2, 1, 1}, {0.0, 0.707, -0.707}).normal({-1, 0, 0}).binormal({0.0, 0.707, 0.707})
          .curvature(5).curvature_derivative(0).torsion(1).torsion_derivative(0).scale(kPrinted707Scale),
      Frame({1, 3, -1}, {0, 1, 0}).normal({-1, 0, 0}).binormal({0, 0, 1}).curvature(0),
  });
}

// Table B.2 prints the z positions as (1.0, 3.0, -1.0); Table B.1 gives z = (0, 1, -1) and
// the x and y rows of B.2 agree with B.1, so the z row is a misprint: B.1's z is tested.

TEST(AppendixB, TableB_2_Frame1) {
  const auto f = convert_or_fail(tableB_1())[0];
  ExpectPosition(f, {"0.0", "0.0", "0.0"});  // z printed 1.0: misprint (Table B.1: 0)
  ExpectSide(f.leave, 2, {{"1.0", "0.0", "0.0"}, {"0.0", "0.0", "0.0"}});  // d3, d4 printed 0: free
}

TEST(AppendixB, TableB_2_Frame2) {
  const auto f = convert_or_fail(tableB_1())[1];
  ExpectPosition(f, {"2.0", "1.0", "1.0"});  // z printed 3.0: misprint (Table B.1: 1)
  for (const auto* side : {&f.approach, &f.leave}) {
    ExpectSide(*side, 4, {{"0.0", "0.707", "-0.707"}, {"-4.9985", "0.0", "0.0"}, {"0.0", "3.5339", "3.5339"},
                          {"0.0", "0.0", "0.0"}});
  }
}

TEST(AppendixB, TableB_2_Frame3) {
  const auto f = convert_or_fail(tableB_1())[2];
  ExpectPosition(f, {"1.0", "3.0", "-1.0"});
  ExpectSide(f.approach, 2, {{"0.0", "1.0", "0.0"}, {"0.0", "0.0", "0.0"}});
}

}  // namespace
}  // namespace geotraj::test
