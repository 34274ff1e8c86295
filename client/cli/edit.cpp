// fulcrum edit: apply one edit batch (Protobuf JSON of fulcrum.v1.EditBatch) to a world.
#include <google/protobuf/util/json_util.h>

#include <ostream>

#include "remote.h"

namespace fulcrum::cli {

int run_edit(const Invocation& inv) {
  int exit_code = kExitOk;
  std::optional<uint64_t> world = world_arg(inv, 0, &exit_code);
  if (!world) return exit_code;
  const std::optional<std::string> file = inv.args.value("file");
  if (!file) return inv.usage_error("missing --file EDITS.json");
  std::string error;
  std::optional<int64_t> expected;
  if (auto t = inv.args.value("expected-tick")) {
    expected = parse_int(*t, 0, int64_t{1} << 62, &error);
    if (!expected) return inv.usage_error("--expected-tick: " + error);
  }
  std::optional<std::string> json = read_file(*file, &error);
  if (!json) return inv.fail(error);
  v1::EditBatch batch;
  auto parsed = google::protobuf::util::JsonStringToMessage(*json, &batch);
  if (!parsed.ok()) return inv.fail(*file + ": " + std::string(parsed.message()));

  auto client = connect_from_args(inv, &exit_code);
  if (!client) return exit_code;
  Result<client::EditResult> r = client->apply_edits(*world, batch, expected);
  if (!r.ok()) return inv.fail(r.status().message());
  inv.out << "world " << *world << ": " << batch.edits_size() << " edits applied at tick "
          << r->tick << ", state hash " << hex64(r->state_hash) << "\n";
  for (const BodyId& b : r->bodies) {
    inv.out << "created body " << b.index << ":" << b.generation << "\n";
  }
  for (const ShapeId& s : r->shapes) {
    inv.out << "created shape " << s.index << ":" << s.generation << "\n";
  }
  for (const JointId& j : r->joints) {
    inv.out << "created joint " << j.index << ":" << j.generation << "\n";
  }
  return kExitOk;
}

}  // namespace fulcrum::cli
