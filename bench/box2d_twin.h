// The Box2D 2.4.1 twin of a Fulcrum scene: the same bodies, shapes, materials, masses and
// joints, built from the very SceneDef Fulcrum builds from, as far as 2.4.1 can express them.
// What it cannot express exactly is counted in TwinNotes so that reports can say so.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <box2d/box2d.h>

#include "fulcrum/scene.h"

namespace fulcrum::bench {

// Mass properties of one scene body as Fulcrum computes them; the twin's dynamic bodies get
// exactly these (b2Body::SetMassData), whatever shapes stand in for Fulcrum's.
struct BodyMass {
  double mass = 0.0;                 // kg (0: static or kinematic)
  double inertia = 0.0;              // about the centre of mass, kg m^2
  Vec2 local_center = Vec2::Zero();  // centre of mass in the body frame, m
};

// Reads every body's mass properties from a freshly built Fulcrum world, in scene order.
std::vector<BodyMass> fulcrum_masses(const SceneDef& scene);

struct TwinOptions {
  // Box2D 2.4.1 puts a skin of b2_polygonRadius (0.01 m) around every polygon. When true, each
  // polygon's core is inset by the skin so that the skinned outline is Fulcrum's outline
  // (corners rounded by 0.01 m); when false, polygons keep Fulcrum's vertices and grow by the
  // skin, so boxes that touch exactly start 0.02 m overlapped.
  bool compensate_skin = true;
};

// What the conversion changed or could not carry over, by kind.
struct TwinNotes {
  int capsules = 0;             // capsule -> one box + two circles on the same body
  int inset_polygons = 0;       // polygon cores inset by the skin
  int rounded_polygons = 0;     // rounded polygons: core offset by the skin less their radius
  int thin_polygons = 0;        // polygons too thin to inset: core b2_linearSlop thick
  int skinned_segments = 0;     // segments and chain links: edges carry the 0.01 m skin
  int wide_filters = 0;         // categories or groups beyond Box2D's 16 bits (truncated)
  int joints = 0;               // joints converted
  int revolute_springs = 0;     // revolute springs dropped (2.4.1 has none)
  int weld_linear_springs = 0;  // weld linear springs dropped (2.4.1 welds soften the angle only)
  int prismatic_springs = 0;    // prismatic springs dropped (2.4.1 has none)

  // One line per kind that occurred, e.g. "550 capsules as a box and two circles".
  std::vector<std::string> lines() const;
};

struct Twin {
  std::unique_ptr<b2World> world;
  std::vector<b2Body*> bodies;  // bodies[i] is scene.bodies[i]
};

// Builds the twin. `masses` is fulcrum_masses(scene).
Twin build_box2d_twin(const SceneDef& scene, const std::vector<BodyMass>& masses,
                      const TwinOptions& options, TwinNotes* notes);

// The largest overlap over the points of the touching, non-sensor contacts, from 2.4.1's
// world manifolds at the bodies' current transforms. The separation includes the skin, so
// with compensate_skin it is the overlap of Fulcrum's outlines.
double box2d_max_penetration(b2World& world);

}  // namespace fulcrum::bench
