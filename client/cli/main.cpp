// fulcrum: the command-line client. Subcommands are listed in the table in commands(); each
// lives in its own file.
#include <iostream>
#include <string>
#include <vector>

#include "args.h"
#include "command.h"
#include "remote.h"

namespace fulcrum::cli {
namespace {

constexpr FlagSpec kSimFlags[] = {
    kSceneFlag,
    kBuiltinFlag,
    {"ticks", "N", "number of ticks to step (>= 0)"},
    {"json", "", "print one JSON object instead of text"},
    {"trace", "FILE", "write figures every --trace-every ticks: CSV, or JSON lines for *.jsonl"},
    {"trace-every", "K", "with --trace: a row every K ticks (default 1)"},
    {"trace-bodies", "I,J:G,...", "with --trace: bodies whose states each row carries (handles)"},
    {"set", "NAME=VALUE", "override a world setting (scene.proto WorldSettings; repeatable)", true},
    {"edits", "FILE",
     "edit script (fulcrum.v1.EditScript JSON; bodies by handle or sceneIndex) applied as it runs"},
};
constexpr FlagSpec kExportFlags[] = {kSceneFlag, kBuiltinFlag};
constexpr FlagSpec kReplayFlags[] = {
    kSceneFlag,
    kBuiltinFlag,
    {"ticks", "N", "record: number of ticks to record; info: list ticks (all, T or FROM-TO)", false,
     true},
    {"out", "FILE", "record: the replay file to write"},
    {"edits", "FILE", "record: edit script (Protobuf JSON of fulcrum.v1.EditScript)"},
    {"set", "NAME=VALUE", "record: override a world setting, as sim --set (repeatable)", true},
    {"keyframes", "K", "record, start: a full snapshot every K ticks (default 60, 0: none)"},
    {"junit", "FILE", "verify: also write a JUnit XML report, one test case per replay"},
    kServerFlag,
    kTokenFileFlag,
    kDeadlineFlag,
};

constexpr FlagSpec kRemoteFlags[] = {kServerFlag, kTokenFileFlag, kDeadlineFlag, kTlsCaFlag,
                                     kTlsNameFlag};
constexpr FlagSpec kHealthFlags[] = {
    kServerFlag,
    kDeadlineFlag,
    kTlsCaFlag,
    kTlsNameFlag,
    {"service", "NAME", "the service to check (default: the whole server)"}};
constexpr FlagSpec kCreateFlags[] = {kSceneFlag,    kServerFlag, kTokenFileFlag,
                                     kDeadlineFlag, kTlsCaFlag,  kTlsNameFlag};
constexpr FlagSpec kStepFlags[] = {
    kServerFlag,
    kTokenFileFlag,
    kDeadlineFlag,
    kTlsCaFlag,
    kTlsNameFlag,
    {"expected-tick", "T", "step only if the world is at tick T"},
    {"trajectory", "FILE.csv",
     "write the bodies' states every --every ticks to FILE.csv ('-': stdout), every sample"},
    {"every", "K", "with --trajectory: a sample every K ticks (default 1)"},
    {"bodies", "I,J:G,...",
     "with --trajectory: the bodies, by handle INDEX or INDEX:GENERATION (default: all)"}};
constexpr FlagSpec kEditFlags[] = {
    kServerFlag,
    kTokenFileFlag,
    kDeadlineFlag,
    kTlsCaFlag,
    kTlsNameFlag,
    {"file", "EDITS.json", "the batch (Protobuf JSON of fulcrum.v1.EditBatch)"},
    {"expected-tick", "T", "apply only if the world is at tick T"}};
constexpr FlagSpec kSnapshotFlags[] = {kServerFlag,
                                       kTokenFileFlag,
                                       kDeadlineFlag,
                                       kTlsCaFlag,
                                       kTlsNameFlag,
                                       {"out", "FILE", "get: the snapshot file to write"},
                                       {"file", "FILE", "restore: the snapshot file to read"}};
constexpr FlagSpec kWatchFlags[] = {
    kServerFlag,
    kTokenFileFlag,
    kDeadlineFlag,
    kTlsCaFlag,
    kTlsNameFlag,
    {"seconds", "S", "stop after S seconds (default: when the stream ends)"},
    {"every", "K", "a frame every K ticks (default 1; late frames are coalesced)"},
    {"bodies", "WHICH", "none, changed or all: the body states each frame carries (default none)"},
    {"quantized", "", "body states in fixed point (implies --bodies changed unless given)"}};

constexpr FlagSpec kRunFlags[] = {
    kServerFlag,
    kTokenFileFlag,
    kDeadlineFlag,
    {"max-catch-up", "N", "ticks one wake may step when the server is behind (default 5)"}};
constexpr FlagSpec kQueryFlags[] = {
    kServerFlag,
    kTokenFileFlag,
    kDeadlineFlag,
    {"all", "", "ray: every hit along the ray, not only the closest"},
    {"category", "BITS", "the query's category bits (default 1; decimal or 0x hex)"},
    {"mask", "BITS", "the query's mask bits (default all)"}};
constexpr FlagSpec kSessionFlags[] = {
    kServerFlag,
    kTokenFileFlag,
    kDeadlineFlag,
    kTlsCaFlag,
    kTlsNameFlag,
    {"players", "N", "open: at most N players (default 8)"},
    {"input-delay", "D", "open: inputs are for ticks at least D ahead (default 0)"},
    {"seal", "RULE", "open: on-step (clock or Step, default) or all-inputs (turn by turn)"},
    {"missing", "RULE", "open: a missing input is none (default) or repeat (the last one)"},
    {"bodies", "I,J:G,...", "join, bot: the bodies the player takes (bot: and pushes)"},
    {"name", "NAME", "join, bot: the player's name (default player, bot)"},
    {"seed", "S", "bot: seeds its random impulses (default 1)"},
    {"impulse", "N_S", "bot: the largest impulse per axis, N s (default 1)"},
    {"report-every", "K", "bot: report its state hashes to the server every K ticks (1-1024)"},
    {"ticks", "N", "bot, watch: stop after N confirmed ticks (default: when the stream ends)"}};
constexpr FlagSpec kViewFlags[] = {
    kServerFlag,
    kTokenFileFlag,
    kDeadlineFlag,
    kTlsCaFlag,
    kTlsNameFlag,
    {"listen", "HOST:PORT", "where the page is served (default 127.0.0.1:8080; port 0: any)"},
    {"world", "ID", "the world the page opens with (default: the first one)"},
    {"replay", "FILE", "play a replay file locally instead of following a server"}};

constexpr Command kCommands[] = {
    {"sim", "build a scene, step it N ticks, print the state hash and accuracy figures",
     "(--scene FILE | --builtin NAME) --ticks N [--json] [--set NAME=VALUE]...\n"
     "       [--edits FILE] [--trace FILE [--trace-every K] [--trace-bodies I,J,...]]",
     "Steps the scene on one thread and reports the final tick, the 64-bit state hash, the\n"
     "wall time per step (split into ticks with bodies awake and ticks with all asleep),\n"
     "World::metrics() at the last tick, and over the whole run the largest penetration,\n"
     "joint error, speed and energy drift (E - E0, E = kinetic + potential, potential = -m g.c\n"
     "of each dynamic body's centre of mass), each with its tick. --set substeps=6 overrides a\n"
     "setting by its proto field name (gravity.y for a nested one), range-checked as scene\n"
     "files are. See docs/sim.md.",
     kSimFlags, 0, run_sim},
    {"scenes", "list the built-in scenes", "", "", {}, 0, run_scenes},
    {"export", "print a scene as JSON (explicit bodies, all settings)",
     "(--scene FILE | --builtin NAME)",
     "The output is a scene file: `fulcrum sim --scene` on it gives the same state hash.",
     kExportFlags, 0, run_export},
    {"replay", "record, verify or describe a replay file",
     "record (--scene FILE | --builtin NAME) --ticks N --out FILE [--edits FILE] [--set N=V]... "
     "[--keyframes K]\n"
     "       fulcrum replay verify (FILE | DIR)... [--junit REPORT.xml]\n"
     "       fulcrum replay info FILE [--ticks [all|T|FROM-TO]]\n"
     "       fulcrum replay start WORLD [--keyframes K]   (on a fulcrum-server)\n"
     "       fulcrum replay stop WORLD\n"
     "       fulcrum replay download (WORLD | NAME) --out FILE",
     "A replay holds the initial snapshot, every edit batch with its tick, every tick's state\n"
     "hash and a keyframe snapshot every K ticks. `verify` re-simulates it and exits 0 when\n"
     "every tick matches; otherwise it exits 1 naming the first divergent tick and, from the\n"
     "keyframe of that tick or the next, the first body, joint or contact field that differs.\n"
     "It takes several files, and directories (their *.replay files, in name order); with\n"
     "--junit it also writes a JUnit XML report for CI systems (docs/replays-in-ci.md).\n"
     "`start`/`stop` record a world on the server (fulcrum-server --replay-dir): every tick\n"
     "with the edit batches applied before it. `download` fetches the world's current or last\n"
     "recording, or a replay by the name `start` printed; a recording in progress comes up to\n"
     "its last complete tick.",
     kReplayFlags, 100000, run_replay},
    {"create", "create a world on a fulcrum-server from a scene file", "--scene FILE",
     "Prints \"world ID created from FILE: ...\"; ID names the world in the other commands.",
     kCreateFlags, 0, run_create},
    {"worlds", "list the worlds on a fulcrum-server", "", "", kRemoteFlags, 0, run_worlds},
    {"step", "step a world on a fulcrum-server N ticks",
     "WORLD N [--expected-tick T] [--trajectory FILE.csv [--every K] [--bodies I,J,...]]",
     "--trajectory streams the states as the server steps and waits for the file to take\n"
     "them (StepTrajectory): one row per body per sample, tick,state_hash,body_index,\n"
     "body_generation,x,y,angle,vx,vy,angular_velocity,awake, doubles exact to the bit.",
     kStepFlags, 2, run_step},
    {"edit", "apply an edit batch to a world on a fulcrum-server",
     "WORLD --file EDITS.json [--expected-tick T]",
     "The batch is atomic: any refused edit leaves the world unchanged, and the error names\n"
     "the edit and field (batch.edits[i].field).",
     kEditFlags, 1, run_edit},
    {"snapshot", "save a world on a fulcrum-server, or restore (roll back / fork) one",
     "get WORLD --out FILE\n"
     "       fulcrum snapshot restore (WORLD | new) --file FILE",
     "`restore new` forks: a new world continues from the snapshot.", kSnapshotFlags, 2,
     run_snapshot},
    {"watch", "follow a world's frames: one line per second (tick, awake bodies, hash)",
     "WORLD [--seconds S] [--every K] [--bodies none|changed|all] [--quantized]",
     "Each line: the newest frame's tick, awake/live bodies and state hash, the frames received\n"
     "(and coalesced on the server) so far, and the bytes received since the previous line per\n"
     "second and per frame. `changed` sends a body when its state changed since the previous\n"
     "frame; --quantized sends it in fixed point (frames.proto, QuantizedBodyFrame), about a\n"
     "third of the bytes; the state hash is the world's exact hash either way.",
     kWatchFlags, 1, run_watch},
    {"run", "run a world on a fulcrum-server in real time (its dt on the server's clock)",
     "WORLD [--max-catch-up N]",
     "The server steps the world once per dt against its monotonic clock until `fulcrum pause`.\n"
     "When the server falls behind, one wake steps at most N ticks and drops the rest of the\n"
     "ticks then due (counted by `fulcrum worlds`). `step` is refused while a world runs;\n"
     "edits apply between two ticks.",
     kRunFlags, 1, run_run},
    {"pause", "stop a world's real-time clock", "WORLD",
     "No tick runs after the reply; the world steps only by `fulcrum step` again.", kRemoteFlags, 1,
     run_pause},
    {"query", "ray cast, AABB overlap or point query on a world on a fulcrum-server",
     "WORLD ray X1 Y1 X2 Y2 [--all]\n"
     "       fulcrum query WORLD aabb XMIN YMIN XMAX YMAX\n"
     "       fulcrum query WORLD point X Y",
     "Against the world at its current tick (m). A ray goes from (X1, Y1) to (X2, Y2); shapes\n"
     "print as INDEX:GENERATION handles. --category/--mask filter like a shape's filter.",
     kQueryFlags, 6, run_query},
    {"stats", "print a fulcrum-server's counters (ticks, step time, frames, refusals)", "",
     "Totals since the server started (GetStats): worlds created, deleted and restored, ticks\n"
     "stepped and step time, streams, frames sent, coalesced and encoded, readers ended for\n"
     "falling too far behind, and refused requests by status code.",
     kRemoteFlags, 0, run_stats},
    {"health", "check that a fulcrum-server is serving (the standard gRPC health check)",
     "[--service NAME]",
     "Prints SERVING and exits 0, or prints NOT_SERVING (a server shutting down) and exits 1;\n"
     "a server that does not answer within --deadline-ms is an error (exit 1). --service\n"
     "checks one service (fulcrum.v1.Physics); default: the whole server. No token needed.\n"
     "The container image's HEALTHCHECK runs it.",
     kHealthFlags, 0, run_health},
    {"session", "open a world as a multiplayer session, join it, play it as a bot, or watch it",
     "open|create WORLD [--players N] [--input-delay D] [--seal on-step|all-inputs]\n"
     "                 [--missing none|repeat]\n"
     "       fulcrum session join WORLD [--bodies I,J] [--name NAME]\n"
     "       fulcrum session bot WORLD --bodies I,J [--ticks N] [--seed S] [--impulse N_S]\n"
     "                 [--report-every K]\n"
     "       fulcrum session watch WORLD [--ticks N]",
     "A bot joins as a player with the bodies named, sends seeded random impulses on them one\n"
     "input per tick, and steps its own copy of the world with every confirmed tick, checking\n"
     "the server's state hash at each (lockstep); `watch` does the same without playing. Both\n"
     "print a line every 60 ticks and exit 1 at the first hash that differs. With --seal\n"
     "on-step the world moves by `fulcrum run` or `fulcrum step`; with all-inputs it steps as\n"
     "soon as every player's input for its next tick is in. With --report-every the bot also\n"
     "reports its hashes to the server (ReportHash) every K ticks, and at a desync sends its\n"
     "snapshot of the tick so that the server names the first field that differs. `join`\n"
     "takes a player slot for another program (Python, C++) and prints its id and secret.",
     kSessionFlags, 2, run_session},
    {"view", "draw a world live in the browser, or play a replay file with a timeline",
     "[--listen HOST:PORT] [--world ID]\n"
     "       fulcrum view --replay FILE [--listen HOST:PORT]",
     "Serves one page (open the printed URL) that draws a world from its frame stream: every\n"
     "shape, joints as lines, sleeping bodies dimmed; a world picker, run, pause and step,\n"
     "zoom (wheel) and pan (drag the background); dragging a body pulls it with a target joint\n"
     "(destroyed on release). With --replay it re-steps the file locally: a timeline seeks any\n"
     "tick and marks the first tick whose hash differs from the file's. Stops on SIGINT or\n"
     "SIGTERM (exit 0). See docs/viewer.md.",
     kViewFlags, 0, run_view},
};

void print_main_help(std::ostream& out) {
  out << "fulcrum: deterministic 2D rigid-body physics\n\n"
         "usage: fulcrum COMMAND [FLAGS]\n"
         "       fulcrum COMMAND --help\n\n"
         "commands:\n";
  for (const Command& c : commands()) {
    std::string name(c.name);
    name.resize(10, ' ');
    out << "  " << name << c.summary << "\n";
  }
  out << "\nexit codes: 0 success, 1 the scene, simulation or server call failed, 2 bad command "
         "line\n";
}

const Command* find_command(std::string_view name) {
  for (const Command& c : commands()) {
    if (c.name == name) return &c;
  }
  return nullptr;
}

int main_impl(const std::vector<std::string>& argv) {
  if (argv.empty()) {
    print_main_help(std::cerr);
    return kExitUsage;
  }
  const std::string& first = argv[0];
  if (first == "--help" || first == "-h" || first == "help") {
    if (first == "help" && argv.size() > 1) {
      const Command* c = find_command(argv[1]);
      if (c == nullptr) {
        std::cerr << "fulcrum: unknown command '" << argv[1] << "'\n";
        return kExitUsage;
      }
      print_command_help(*c, std::cout);
    } else {
      print_main_help(std::cout);
    }
    return kExitOk;
  }
  const Command* command = find_command(first);
  if (command == nullptr) {
    std::cerr << "fulcrum: unknown command '" << first << "' (see fulcrum --help)\n";
    return kExitUsage;
  }

  Invocation inv{*command, Args(), std::cout, std::cerr};
  std::string error;
  std::span<const std::string> rest(argv.begin() + 1, argv.end());
  if (!Args::parse(rest, command->flags, &inv.args, &error)) return inv.usage_error(error);
  if (inv.args.help()) {
    print_command_help(*command, std::cout);
    return kExitOk;
  }
  const auto& positional = inv.args.positional();
  if (static_cast<int>(positional.size()) > command->max_positional) {
    return inv.usage_error("unexpected argument '" + positional[command->max_positional] + "'");
  }
  return command->run(inv);
}

}  // namespace

std::span<const Command> commands() {
  return kCommands;
}

}  // namespace fulcrum::cli

int main(int argc, char** argv) {
  std::vector<std::string> args(argv + 1, argv + argc);
  int code = fulcrum::cli::main_impl(args);
  std::cout.flush();
  // A failed write (closed pipe, full disk) must not look like success.
  if (code == fulcrum::cli::kExitOk && !std::cout) return fulcrum::cli::kExitError;
  return code;
}
