#include "hard_case_probes.h"

#include <algorithm>
#include <cmath>
#include <variant>

#include "fulcrum/trig.h"

namespace fulcrum::bench {

std::vector<Vec2> centers(const View& v) {
  std::vector<Vec2> out;
  out.reserve(v.body_count());
  for (size_t i = 0; i < v.body_count(); ++i) out.push_back(v.center(i));
  return out;
}

bool all_finite(const View& v) {
  for (size_t i = 0; i < v.body_count(); ++i) {
    BodyPose p = v.body(i);
    if (!is_finite(p.center) || !is_finite(p.velocity) || !std::isfinite(p.spin)) return false;
  }
  return true;
}

namespace {

// Penetration limit check shared by the contact cases ("<= 2 x slop" or "< limit"), on the
// runner's kMaxPenetration.
void check_penetration(Measures* m, double limit, bool inclusive) {
  double p = m->value[kMaxPenetration].value_or(0.0);
  bool ok = inclusive ? p <= limit : p < limit;
  m->check(ok, "penetration " + num(p) + (inclusive ? " > " : " >= ") + num(limit));
}

// How far the body centres are now from `from`: the largest distance, and how many moved at
// least `bound` (at_least) or more than it.
struct Moves {
  double largest = 0.0;
  int count = 0;
};
Moves moves_from(const std::vector<Vec2>& from, const View& v, double bound, bool at_least) {
  Moves out;
  for (size_t i = 0; i < from.size(); ++i) {
    double d = distance(from[i], v.center(i));
    out.largest = std::max(out.largest, d);
    out.count += at_least ? d >= bound : d > bound;
  }
  return out;
}

// Case 1: the top box moves < 5 cm sideways; penetration <= 2 x slop.
class StackProbe : public Probe {
  std::vector<Vec2> start_;

 public:
  void begin(const View& v) override { start_ = centers(v); }
  void finish(const View& v, Measures* m) override {
    std::vector<Vec2> end = centers(v);
    double drift = std::abs(end.back().x() - start_.back().x());
    int out = 0;
    for (size_t i = 1; i < end.size(); ++i) out += std::abs(end[i].x() - start_[i].x()) >= 0.05;
    m->set(kDisplacement, drift);
    m->set(kBodiesOut, out);
    m->check(drift < 0.05, "top drift " + num(drift) + " >= 0.05");
    check_penetration(m, 2.0 * v.scene().settings.linear_slop, true);
  }
};

// Cases 2 and 3: no box moves more than 0.5 m from where it was built; penetration <= 2 x slop;
// for the large pyramid also the top box drops < 10 cm after settling (the test settles 200 of
// 500 ticks; a shorter run settles the same 2/5 of the ticks it runs).
class PyramidProbe : public Probe {
  bool top_drop_;
  int settle_tick_ = 0;
  double settled_y_ = 0.0;
  std::vector<Vec2> built_;

 public:
  explicit PyramidProbe(bool top_drop) : top_drop_(top_drop) {}
  void begin(const View& v) override {
    built_ = centers(v);
    settle_tick_ = v.ticks() * 2 / 5;
  }
  void after_tick(const View& v) override {
    if (top_drop_ && v.tick() == settle_tick_) settled_y_ = v.center(v.body_count() - 1).y();
  }
  void finish(const View& v, Measures* m) override {
    Moves moved = moves_from(built_, v, 0.5, false);
    m->set(kDisplacement, moved.largest);
    m->set(kBodiesOut, moved.count);
    m->check(moved.count == 0, std::to_string(moved.count) + " boxes moved > 0.5 m");
    if (top_drop_) {
      double drop = settled_y_ - v.center(v.body_count() - 1).y();
      m->check(drop < 0.10, "top drop " + num(drop) + " >= 0.1");
    }
    check_penetration(m, 2.0 * v.scene().settings.linear_slop, true);
  }
};

// Case 4: no box centre moves 10 cm or more; penetration < 5 cm.
class MassRatio100Probe : public Probe {
  std::vector<Vec2> start_;

 public:
  void begin(const View& v) override { start_ = centers(v); }
  void finish(const View& v, Measures* m) override {
    Moves moved = moves_from(start_, v, 0.10, true);
    m->set(kDisplacement, moved.largest);
    m->set(kBodiesOut, moved.count);
    m->check(moved.largest < 0.10, "moved " + num(moved.largest) + " >= 0.1");
    check_penetration(m, 0.05, false);
  }
};

// Case 5: the small boxes (bodies 1 and 2) stay within 0.25 m of their start sideways and above
// 0.4 m at every tick, the big box (body 3) ends above 10.5 m; penetration < 10 cm.
class MassRatio400Probe : public Probe {
  double x0_[2] = {0.0, 0.0};
  double worst_dx_ = 0.0, lowest_ = 1e300;

 public:
  void begin(const View& v) override {
    for (int k = 0; k < 2; ++k) x0_[k] = v.center(1 + k).x();
  }
  void after_tick(const View& v) override {
    for (int k = 0; k < 2; ++k) {
      Vec2 p = v.center(1 + k);
      worst_dx_ = std::max(worst_dx_, std::abs(p.x() - x0_[k]));
      lowest_ = std::min(lowest_, p.y());
    }
  }
  void finish(const View& v, Measures* m) override {
    double big_y = v.center(3).y();
    m->set(kDisplacement, worst_dx_);
    m->set(kBodiesOut, (worst_dx_ >= 0.25) + (lowest_ <= 0.4) + (big_y <= 10.5));
    m->check(worst_dx_ < 0.25, "small box pushed " + num(worst_dx_) + " >= 0.25");
    m->check(lowest_ > 0.4, "small box down to " + num(lowest_) + " <= 0.4");
    m->check(big_y > 10.5, "big box at " + num(big_y) + " <= 10.5");
    check_penetration(m, 0.10, false);
  }
};

// Case 6: separated within 2 s (overlap <= 2 x slop at 2 s), no body faster than 3 m/s at any
// tick (the runner's kMaxSpeed), and no centre moves 5 cm or more from 2 s to the end (5 s).
class OverlapProbe : public Probe {
  int settle_tick_ = 0;
  double overlap_at_settle_ = 0.0;
  std::vector<Vec2> settled_;

 public:
  void begin(const View& v) override { settle_tick_ = v.ticks() * 2 / 5; }
  void after_tick(const View& v) override {
    if (v.tick() != settle_tick_) return;
    overlap_at_settle_ = v.max_penetration();
    settled_ = centers(v);
  }
  void finish(const View& v, Measures* m) override {
    Moves moved = moves_from(settled_, v, 0.05, true);
    double fastest = m->value[kMaxSpeed].value_or(0.0);
    m->set(kDisplacement, moved.largest);
    m->set(kBodiesOut, moved.count);
    double slop2 = 2.0 * v.scene().settings.linear_slop;
    m->check(overlap_at_settle_ <= slop2,
             "overlap at 2 s " + num(overlap_at_settle_) + " > " + num(slop2));
    m->check(fastest < 3.0, "speed " + num(fastest) + " >= 3");
    m->check(moved.largest < 0.05, "moved after 2 s " + num(moved.largest) + " >= 0.05");
  }
};

// Case 7: the crown (body 9) drops < 2 cm from where it was built, at every tick.
class ArchProbe : public Probe {
  double y0_ = 0.0, worst_ = 0.0;

 public:
  void begin(const View& v) override { y0_ = v.center(9).y(); }
  void after_tick(const View& v) override { worst_ = std::max(worst_, y0_ - v.center(9).y()); }
  void finish(const View&, Measures* m) override {
    m->set(kDisplacement, worst_);
    m->check(worst_ < 0.02, "crown drop " + num(worst_) + " >= 0.02");
  }
};

// Case 8: every circle centre (bodies 4 on; 0-3 are the walls) stays inside the walls' inner
// faces (|x|, |y| < 10.5) at every tick, and kinetic energy after 3 s never rises above its
// value at 3 s (beyond 1e-9 of it: rounding). energy drift = (largest KE after 3 s) / (KE at
// 3 s) - 1.
class ConfinedProbe : public Probe {
  int ref_tick_ = 0;
  double extent_ = 0.0, ke_ref_ = 0.0, ke_max_ = 0.0;
  std::vector<bool> out_;

 public:
  void begin(const View& v) override {
    ref_tick_ = v.ticks() * 3 / 10;
    out_.assign(v.body_count(), false);
  }
  void after_tick(const View& v) override {
    for (size_t k = 4; k < v.body_count(); ++k) {
      Vec2 p = v.center(k);
      double e = std::max(std::abs(p.x()), std::abs(p.y()));
      extent_ = std::max(extent_, e);
      if (e >= 10.5) out_[k] = true;
    }
    if (v.tick() == ref_tick_) ke_ref_ = ke_max_ = v.kinetic_energy();
    if (v.tick() > ref_tick_) ke_max_ = std::max(ke_max_, v.kinetic_energy());
  }
  void finish(const View&, Measures* m) override {
    double rise = ke_ref_ > 0.0 ? ke_max_ / ke_ref_ - 1.0 : (ke_max_ > 0.0 ? 1e300 : 0.0);
    m->set(kDisplacement, extent_);
    m->set(kBodiesOut, static_cast<double>(std::count(out_.begin(), out_.end(), true)));
    m->set(kEnergyDrift, std::max(rise, 0.0));
    m->check(extent_ < 10.5, "a circle reached " + num(extent_) + " >= 10.5");
    m->check(rise <= 1e-9, "KE rose " + num(rise) + " x after 3 s");
  }
};

// Cases 9, 10, 11 and 19: the largest joint separation (the runner's kJointError) stays under
// `limit` at every tick. The chains (10, 19) also never gain mechanical energy (beyond 1e-6 of
// |E0|: rounding); the bridge (11) holds a steady sag: its middle plank (body 81: body 0 is
// the ground, 1 the anchor, so plank 79) varies in height by less than 1 cm over the last
// second (ticks N-59..N), at rest to the eye against its ~16 m sag. The scene table's bridge
// is undamped, and no solver setting of Fulcrum's settles it within 10 s (it swings on its
// stretched joints); Case11Bridge in tests/engine/joint_cases_test.cpp measures the same way
// on the bridge with its planks damped at 2 /s, which passes at the defaults.
class JointProbe : public Probe {
  double limit_;
  bool energy_, sag_;
  double e0_ = 0.0, e_max_ = 0.0, sag_lo_ = 1e300, sag_hi_ = -1e300;

 public:
  JointProbe(double limit, bool energy, bool sag) : limit_(limit), energy_(energy), sag_(sag) {}
  void begin(const View& v) override {
    if (energy_) e0_ = e_max_ = v.mechanical_energy();
  }
  void after_tick(const View& v) override {
    if (energy_) e_max_ = std::max(e_max_, v.mechanical_energy());
    if (sag_ && v.tick() > v.ticks() - 60) {
      double y = v.center(81).y();
      sag_lo_ = std::min(sag_lo_, y);
      sag_hi_ = std::max(sag_hi_, y);
    }
  }
  void finish(const View& v, Measures* m) override {
    double err = m->value[kJointError].value_or(0.0);
    m->check(err < limit_, "joint error " + num(err) + " >= " + num(limit_));
    if (energy_) {
      double drift = (e_max_ - e0_) / std::abs(e0_);
      m->set(kEnergyDrift, drift);
      m->check(drift <= 1e-6, "energy gain " + num(drift) + " of |E0|");
    }
    if (sag_) {
      double swing = sag_hi_ - sag_lo_;
      m->set(kDisplacement, swing);
      m->check(swing < 0.01, "sag swings " + num(swing) + " m in the last second");
      // A bridge that sags onto the ground 20 m below (ground top y = -20) is steady without
      // hanging at all: planks (bodies 2..161) whose centres end below -19.5 m count as lying
      // on it.
      int grounded = 0;
      for (size_t i = 2; i < 162; ++i) grounded += v.center(i).y() < -19.5 ? 1 : 0;
      m->set(kBodiesOut, grounded);
      m->check(grounded == 0, std::to_string(grounded) + " planks lie on the ground");
    }
  }
};

// Case 12: every joint within 5 cm (the runner's kJointError) and no limit passed by 0.05 rad
// or more at any tick, and every ragdoll did fall (each pelvis, bodies 1 + 11 i, ends below
// 2 m).
class RagdollProbe : public Probe {
  double limit_error_ = 0.0;

 public:
  void after_tick(const View& v) override {
    for (size_t k = 0; k < v.joint_count(); ++k) {
      limit_error_ = std::max(limit_error_, v.joint(k).limit_error);
    }
  }
  void finish(const View& v, Measures* m) override {
    double err = m->value[kJointError].value_or(0.0);
    int standing = 0;
    for (size_t i = 1; i < v.body_count(); i += 11) standing += v.center(i).y() >= 2.0;
    m->set(kLimitError, limit_error_);
    m->set(kBodiesOut, standing);
    m->check(err < 0.05, "joint error " + num(err) + " >= 0.05");
    m->check(limit_error_ < 0.05, "limit passed by " + num(limit_error_) + " rad");
    m->check(standing == 0, std::to_string(standing) + " ragdolls above 2 m");
  }
};

// Case 13: no distance joint stretched 5 % or more ((length - rest) / rest), sampled every
// tick through the first half second and every 5th tick after, as the cloth test samples it.
class ClothProbe : public Probe {
  double worst_ = 0.0;

 public:
  void after_tick(const View& v) override {
    int i = v.tick() - 1;
    if (i > 30 && i % 5 != 4) return;
    for (size_t k = 0; k < v.joint_count(); ++k) {
      const auto* d = std::get_if<DistanceJointDef>(&v.scene().joints[k].def);
      if (d == nullptr) continue;
      worst_ = std::max(worst_, (v.joint(k).length - d->length) / d->length);
    }
  }
  void finish(const View&, Measures* m) override {
    m->set(kStretch, worst_);
    m->check(worst_ < 0.05, "stretch " + num(worst_) + " >= 0.05");
  }
};

// Case 14: successive bounce heights in ratio e^2 = 0.25 within 2 %: each bounce's (leave /
// impact speed)^2, the first two launch-height ratios, the third with the flight allowance
// 2 g h / v (symplectic Euler, substep h), and the first apex over the drop height, as
// tests/engine/hard_cases_test.cpp Case14Bounce checks them. analytic error = the largest
// |ratio - 0.25| / 0.25 of those (the third net of its flight allowance). The ball is the last
// body.
class BounceProbe : public Probe {
  std::vector<double> apex_, impact_, leave_;
  double prev_vy_ = 0.0, prev_y_ = 0.0;

 public:
  void after_tick(const View& v) override {
    const double g = 10.0, r = 0.5;
    BodyPose s = v.body(v.body_count() - 1);
    double vy = s.velocity.y();
    if (prev_vy_ > 0.0 && vy <= 0.0) apex_.push_back(s.center.y() - r);
    if (prev_vy_ < -1.0 && vy > 0.0) {
      impact_.push_back(std::sqrt(prev_vy_ * prev_vy_ + 2.0 * g * (prev_y_ - r)));
      leave_.push_back(vy);
    }
    prev_vy_ = vy;
    prev_y_ = s.center.y();
  }
  void finish(const View& v, Measures* m) override {
    const double g = 10.0, tolerance = 0.02 * 0.25, h0 = 10.0 - 0.5;
    const double h = v.scene().settings.dt / v.scene().settings.substeps;
    double worst = 0.0;
    // The error beyond any allowance the test grants on top of the 2 %, so that it passes at
    // 0.02 for every check.
    auto ratio = [&](double value, double allowed, const std::string& what) {
      worst = std::max(worst, (std::abs(value - 0.25) - (allowed - tolerance)) / 0.25);
      m->check(std::abs(value - 0.25) <= allowed, what + " ratio " + num(value, 4));
    };
    m->check(leave_.size() >= 3 && !apex_.empty(),
             std::to_string(leave_.size()) + " bounces (3 needed)");
    for (size_t i = 0; i < leave_.size(); ++i) {
      ratio(leave_[i] * leave_[i] / (impact_[i] * impact_[i]), tolerance,
            "bounce " + std::to_string(i + 1));
    }
    std::vector<double> heights{h0};
    for (double vl : leave_) heights.push_back(vl * vl / (2.0 * g));
    for (size_t i = 1; i < heights.size() && i <= 3; ++i) {
      double allowed = tolerance + (i == 3 ? 0.25 * 2.0 * g * h / leave_[1] : 0.0);
      ratio(heights[i] / heights[i - 1], allowed, "height " + std::to_string(i));
    }
    if (!apex_.empty()) ratio(apex_[0] / h0, tolerance, "apex");
    m->set(kAnalytic, worst);
  }
};

// Case 15: the box (the last body) slides v^2 / (2 mu g) = 2.5 m within 2 % and is at rest
// (< 1 mm/s) at the end. analytic error = |distance - 2.5| / 2.5.
class SlideProbe : public Probe {
  double x0_ = 0.0;

 public:
  void begin(const View& v) override { x0_ = v.center(v.body_count() - 1).x(); }
  void finish(const View& v, Measures* m) override {
    BodyPose s = v.body(v.body_count() - 1);
    double d = s.center.x() - x0_, speed = length(s.velocity);
    m->set(kAnalytic, std::abs(d - 2.5) / 2.5);
    m->check(std::abs(d - 2.5) <= 0.02 * 2.5, "slid " + num(d, 4) + " m");
    m->check(speed < 1e-3, "still moving at " + num(speed));
  }
};

// Case 16: every period (between zero crossings in the same direction, interpolated between
// ticks) within 0.5 % of 2 pi sqrt(L / g), at least 8 of them, and no half swing wider than the
// release amplitude by 0.1 %. analytic error = the largest |period - T| / T; energy drift =
// the widest half swing / the release amplitude - 1. The bob is body 1, on a 1 m rod; the
// release amplitude is its x at tick 0 (sin 5 deg in the sweep's scene).
class PendulumProbe : public Probe {
  double release_ = 0.0;
  double prev_x_ = 0.0, last_crossing_ = -1.0, peak_ = 0.0;
  std::vector<double> periods_, amplitudes_;

 public:
  void begin(const View& v) override { release_ = prev_x_ = peak_ = v.center(1).x(); }
  void after_tick(const View& v) override {
    double x = v.center(1).x(), dt = v.scene().settings.dt;
    peak_ = std::max(peak_, std::abs(x));
    if (prev_x_ > 0.0 && x <= 0.0) {
      double t = (v.tick() - 1 + prev_x_ / (prev_x_ - x)) * dt;
      if (last_crossing_ >= 0.0) periods_.push_back(t - last_crossing_);
      last_crossing_ = t;
      amplitudes_.push_back(peak_);
      peak_ = 0.0;
    }
    prev_x_ = x;
  }
  void finish(const View&, Measures* m) override {
    const double expected = 2.0 * kPi * std::sqrt(1.0 / 10.0);
    double worst = 0.0, widest = 0.0;
    for (double p : periods_) worst = std::max(worst, std::abs(p - expected) / expected);
    for (double a : amplitudes_) widest = std::max(widest, a / release_ - 1.0);
    m->set(kAnalytic, worst);
    m->set(kEnergyDrift, std::max(widest, 0.0));
    m->check(periods_.size() >= 8, std::to_string(periods_.size()) + " periods (8 needed)");
    m->check(worst <= 0.005, "period off by " + num(worst));
    m->check(widest < 0.001, "amplitude grew " + num(widest));
  }
};

// Case 18: every box centre (bodies 2 on) stays inside the drum's (body 1) inner square, 9.5 m
// from its centre along both drum axes, sampled every 10th tick, and the motor holds 25 deg/s
// within 1 %.
class TumblerProbe : public Probe {
  double worst_ = 0.0;
  std::vector<bool> out_;

 public:
  void begin(const View& v) override { out_.assign(v.body_count(), false); }
  void after_tick(const View& v) override {
    if (v.tick() % 10 != 0) return;
    Transform xf = v.body(1).transform;
    for (size_t k = 2; k < v.body_count(); ++k) {
      Vec2 local = xf.inv_apply(v.center(k));
      double e = std::max(std::abs(local.x()), std::abs(local.y()));
      worst_ = std::max(worst_, e);
      if (e >= 9.5) out_[k] = true;
    }
  }
  void finish(const View& v, Measures* m) override {
    const double speed = 25.0 * kPi / 180.0;
    double w = v.body(1).spin;
    m->set(kDisplacement, worst_);
    m->set(kBodiesOut, static_cast<double>(std::count(out_.begin(), out_.end(), true)));
    m->check(worst_ < 9.5, "a box reached " + num(worst_) + " >= 9.5");
    m->check(std::abs(w - speed) <= 0.01 * speed, "drum turns at " + num(w) + " rad/s");
  }
};

// Case 20: the planks (bodies 1 on, from the bottom up; body 0 is the ground, its top face at
// y = 0) stand: the top plank's centre moves less than 1 cm from where it was built, at every
// tick; penetration <= 2 x slop (the runner's kMaxPenetration); and none passes through
// another: at every tick each plank's centre stays above the centre of the plank below it, and
// the bottom plank's above the ground's top. The penetration allowed (2 x the default 5 mm
// slop) is five planks' thickness, so the order is the test that a plank went through.
class PlanksProbe : public Probe {
  Vec2 top0_ = Vec2::Zero();
  double top_move_ = 0.0;
  std::vector<bool> through_;

 public:
  void begin(const View& v) override {
    top0_ = v.center(v.body_count() - 1);
    through_.assign(v.body_count(), false);
  }
  void after_tick(const View& v) override {
    top_move_ = std::max(top_move_, distance(top0_, v.center(v.body_count() - 1)));
    double below = 0.0;  // the ground's top face
    for (size_t i = 1; i < v.body_count(); ++i) {
      double y = v.center(i).y();
      if (!(y > below)) through_[i] = true;
      below = y;
    }
  }
  void finish(const View& v, Measures* m) override {
    const int through = static_cast<int>(std::count(through_.begin(), through_.end(), true));
    m->set(kDisplacement, top_move_);
    m->set(kBodiesOut, through);
    m->check(top_move_ < 0.01, "top plank moved " + num(top_move_) + " >= 0.01");
    check_penetration(m, 2.0 * v.scene().settings.linear_slop, true);
    m->check(through == 0, std::to_string(through) + " planks passed through the one below");
  }
};

// Any other scene: how far the bodies moved, no criterion.
class MovedProbe : public Probe {
  std::vector<Vec2> start_;

 public:
  void begin(const View& v) override { start_ = centers(v); }
  void finish(const View& v, Measures* m) override {
    Moves moved = moves_from(start_, v, 0.5, false);
    m->set(kDisplacement, moved.largest);
    m->set(kBodiesOut, moved.count);
    m->judged = false;
  }
};

}  // namespace

std::unique_ptr<Probe> hard_case_probe(int id) {
  switch (id) {
    case 1:
      return std::make_unique<StackProbe>();
    case 2:
      return std::make_unique<PyramidProbe>(true);
    case 3:
      return std::make_unique<PyramidProbe>(false);
    case 4:
      return std::make_unique<MassRatio100Probe>();
    case 5:
      return std::make_unique<MassRatio400Probe>();
    case 6:
      return std::make_unique<OverlapProbe>();
    case 7:
      return std::make_unique<ArchProbe>();
    case 8:
      return std::make_unique<ConfinedProbe>();
    case 9:
      return std::make_unique<JointProbe>(0.10, false, false);
    case 10:
      return std::make_unique<JointProbe>(0.05, true, false);
    case 11:
      return std::make_unique<JointProbe>(0.05, false, true);
    case 12:
      return std::make_unique<RagdollProbe>();
    case 13:
      return std::make_unique<ClothProbe>();
    case 14:
      return std::make_unique<BounceProbe>();
    case 15:
      return std::make_unique<SlideProbe>();
    case 16:
      return std::make_unique<PendulumProbe>();
    case 18:
      return std::make_unique<TumblerProbe>();
    case 19:
      return std::make_unique<JointProbe>(0.05, true, false);
    case 20:
      return std::make_unique<PlanksProbe>();
    default:
      return nullptr;
  }
}

std::unique_ptr<Probe> moved_probe() {
  return std::make_unique<MovedProbe>();
}

}  // namespace fulcrum::bench
