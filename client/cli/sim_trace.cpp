#include "sim_trace.h"

#include <cmath>
#include <cstdio>

namespace fulcrum::cli {
namespace {

// 17 significant digits: any double prints and reads back to the same bits. JSON has no NaN or
// infinity; they print as null there (CSV keeps "nan", "inf").
std::string number(double v, bool json) {
  if (json && !std::isfinite(v)) return "null";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

}  // namespace

TraceWriter::TraceWriter(const std::string& path, std::vector<BodyId> bodies, bool jsonl)
    : path_(path), bodies_(std::move(bodies)), jsonl_(jsonl) {}

Result<std::unique_ptr<TraceWriter>> TraceWriter::open(const std::string& path,
                                                       std::vector<BodyId> bodies) {
  const bool jsonl = path.size() >= 6 && path.compare(path.size() - 6, 6, ".jsonl") == 0;
  std::unique_ptr<TraceWriter> w(new TraceWriter(path, std::move(bodies), jsonl));
  w->out_.open(path, std::ios::binary | std::ios::trunc);
  if (!w->out_) return not_found(path + ": cannot write the trace file");
  if (!jsonl) {
    w->out_ << "tick,state_hash,awake_bodies,contacts,max_penetration,max_joint_error,"
               "kinetic_energy,potential_energy,energy";
    // Each body's columns are named after its handle: b3_x, b3_y, ... (b3g2_x for generation 2).
    for (const BodyId& b : w->bodies_) {
      std::string p = "b" + std::to_string(b.index) +
                      (b.generation == 1 ? "" : "g" + std::to_string(b.generation)) + "_";
      w->out_ << "," << p << "x," << p << "y," << p << "angle," << p << "vx," << p << "vy," << p
              << "angular_velocity," << p << "awake";
    }
    w->out_ << "\n";
  }
  return w;
}

void TraceWriter::write(const World& world, const WorldMetrics& m) {
  const bool json = jsonl_;
  const std::string hash = World::hash_text(world.state_hash());
  const double energy = m.kinetic_energy + m.potential_energy;
  if (json) {
    out_ << "{\"tick\":" << m.tick << ",\"stateHash\":\"" << hash
         << "\",\"awakeBodies\":" << m.awake_body_count << ",\"contacts\":" << m.contact_count
         << ",\"maxPenetration\":" << number(m.max_penetration, true)
         << ",\"maxJointError\":" << number(m.max_joint_error, true)
         << ",\"kineticEnergy\":" << number(m.kinetic_energy, true)
         << ",\"potentialEnergy\":" << number(m.potential_energy, true)
         << ",\"energy\":" << number(energy, true) << ",\"bodies\":[";
  } else {
    out_ << m.tick << "," << hash << "," << m.awake_body_count << "," << m.contact_count << ","
         << number(m.max_penetration, false) << "," << number(m.max_joint_error, false) << ","
         << number(m.kinetic_energy, false) << "," << number(m.potential_energy, false) << ","
         << number(energy, false);
  }
  for (size_t i = 0; i < bodies_.size(); ++i) {
    const BodyId& id = bodies_[i];
    // A body not (or no longer) in the world: empty cells, or "alive": false.
    Result<BodyState> s = world.body_state(id);
    if (json) {
      out_ << (i > 0 ? "," : "") << "{\"index\":" << id.index
           << ",\"generation\":" << id.generation;
      if (!s.ok()) {
        out_ << ",\"alive\":false}";
        continue;
      }
      out_ << ",\"alive\":true,\"x\":" << number(s->transform.p.x(), true)
           << ",\"y\":" << number(s->transform.p.y(), true)
           << ",\"angle\":" << number(s->transform.q.angle(), true)
           << ",\"vx\":" << number(s->linear_velocity.x(), true)
           << ",\"vy\":" << number(s->linear_velocity.y(), true)
           << ",\"angularVelocity\":" << number(s->angular_velocity, true)
           << ",\"awake\":" << (s->awake ? "true" : "false") << "}";
    } else if (!s.ok()) {
      out_ << ",,,,,,,";
    } else {
      out_ << "," << number(s->transform.p.x(), false) << "," << number(s->transform.p.y(), false)
           << "," << number(s->transform.q.angle(), false) << ","
           << number(s->linear_velocity.x(), false) << "," << number(s->linear_velocity.y(), false)
           << "," << number(s->angular_velocity, false) << "," << (s->awake ? 1 : 0);
    }
  }
  out_ << (json ? "]}\n" : "\n");
}

Status TraceWriter::close() {
  out_.flush();
  const bool ok = static_cast<bool>(out_);
  out_.close();
  if (!ok) return Status(StatusCode::kInternal, path_ + ": writing the trace failed");
  return {};
}

}  // namespace fulcrum::cli
