// Revolute joint: preparation. The passes' functions are in revolute_joint.h.
#include "revolute_joint.h"

#include "world_impl.h"

namespace fulcrum {

void prepare_revolute_joint(const Joint& j, JointRow& r, const ScalarBody& a, const ScalarBody& b) {
  double k = a.inv_inertia + b.inv_inertia;
  r.axial_mass = k > 0.0 ? 1.0 / k : 0.0;
  (void)j;
}

}  // namespace fulcrum
