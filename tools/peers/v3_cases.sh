#!/usr/bin/env bash
# Box2D v3 on three of Fulcrum's accuracy questions, measured the way Fulcrum's tools measure
# Fulcrum: hard case 11 (the undamped bridge, with and without hinge friction), v3's own
# large pyramid (how compressed it ends) and v3's own joint grid (hard case 9: how far its
# joints pull apart). Builds v3 from ../shared/peers/ when /tmp/box2d-v3
# lacks it, then compiles the three programs beside this script against its double build.
# Not part of CI: it measures a peer. docs/accuracy.md and docs/performance.md quote it.
# usage: tools/peers/v3_cases.sh
set -euo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
peers=${PEERS_DIR:-$here/../../../shared/peers}
v3=${BOX2D_V3_DIR:-/tmp/box2d-v3}
[ -f "$v3/double/src/libbox2d.a" ] || "$peers/build_box2d_v3.sh" "$v3" >/dev/null
out=$(mktemp -d)
for prog in v3_bridge v3_pyramid v3_joint_grid; do
  cc -O2 -std=c17 -DBOX2D_DOUBLE_PRECISION -I"$v3/src/include" "$here/$prog.c" \
    "$v3/double/src/libbox2d.a" -lm -lpthread -o "$out/$prog"
done
"$out/v3_bridge"
"$out/v3_bridge" 200
"$out/v3_pyramid"
"$out/v3_joint_grid"
rm -rf "$out"
