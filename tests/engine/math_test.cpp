// The inline 2D math of math.h: rotations as unit complex numbers and rigid transforms.
#include "fulcrum/math.h"

#include <gtest/gtest.h>

#include "fulcrum/trig.h"

namespace fulcrum {
namespace {

// Products and inverses compose like angles; 1e-15 is a few ulps of values of order 1.
TEST(MathTest, RotationsComposeLikeAngles) {
  Rot a = Rot::from_angle(0.7), b = Rot::from_angle(-1.9);
  EXPECT_NEAR(mul(a, b).angle(), 0.7 - 1.9, 1e-15);
  EXPECT_NEAR(inv_mul(a, b).angle(), -1.9 - 0.7, 1e-15);
  Vec2 v(1.5, -0.25);
  Vec2 there_and_back = a.inv_rotate(a.rotate(v));
  EXPECT_NEAR(there_and_back.x(), v.x(), 1e-15);
  EXPECT_NEAR(there_and_back.y(), v.y(), 1e-15);
  EXPECT_NEAR(length(a.rotate(v)), length(v), 1e-15);  // rotations keep lengths
}

TEST(MathTest, TransformsInvertAndCompose) {
  Transform a{Vec2(1.0, 2.0), Rot::from_angle(0.3)};
  Transform b{Vec2(-4.0, 0.5), Rot::from_angle(2.2)};
  Vec2 p(0.25, -3.0);
  Vec2 direct = a.apply(b.apply(p));
  Vec2 composed = mul(a, b).apply(p);
  EXPECT_NEAR(direct.x(), composed.x(), 1e-14);
  EXPECT_NEAR(direct.y(), composed.y(), 1e-14);
  Vec2 local = inv_mul(a, b).apply(p);  // b's point seen from a
  Vec2 expected = a.inv_apply(b.apply(p));
  EXPECT_NEAR(local.x(), expected.x(), 1e-14);
  EXPECT_NEAR(local.y(), expected.y(), 1e-14);
}

TEST(MathTest, CrossProductsFollowTheRightHandRule) {
  Vec2 x(1.0, 0.0), y(0.0, 1.0);
  EXPECT_EQ(cross(x, y), 1.0);
  EXPECT_EQ(cross(y, x), -1.0);
  // w x r for a counter-clockwise spin w = 2 at r = (1, 0) moves along +y.
  EXPECT_EQ(cross(2.0, x), Vec2(0.0, 2.0));
  EXPECT_EQ(cross(x, 2.0), Vec2(0.0, -2.0));
  EXPECT_EQ(left_perp(x), y);
  EXPECT_EQ(right_perp(y), x);
}

TEST(MathTest, BoxesOverlapContainAndGrow) {
  AABB a{Vec2(0, 0), Vec2(2, 1)}, b{Vec2(1.5, 0.5), Vec2(3, 3)}, c{Vec2(2.5, 0), Vec2(3, 0.4)};
  EXPECT_TRUE(a.overlaps(b));
  EXPECT_FALSE(a.overlaps(c));
  EXPECT_TRUE(union_of(a, b).contains(a));
  EXPECT_TRUE(a.fattened(0.1).contains(a));
  EXPECT_FALSE(a.contains(a.fattened(0.1)));
  EXPECT_DOUBLE_EQ(a.perimeter(), 6.0);
}

}  // namespace
}  // namespace fulcrum
