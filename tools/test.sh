#!/usr/bin/env bash
# The whole test suite: install what is missing, build with warnings as errors, run every test
# through ctest in parallel.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/setup.sh"
fulcrum_install_packages
fulcrum_build
cd "$FULCRUM_BUILD"
ctest --output-on-failure -j "$(nproc)" --timeout 900
