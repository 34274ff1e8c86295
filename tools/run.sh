#!/usr/bin/env bash
# The main job: install what is missing, build, and simulate the default scene headless,
# printing a short summary with the final state hash.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/setup.sh"
fulcrum_install_packages
fulcrum_build
"$FULCRUM_BUILD/bin/fulcrum" sim --scene "$FULCRUM_ROOT/scenes/pyramid.json" --ticks 600 "$@"
