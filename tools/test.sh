#!/usr/bin/env bash
# The whole test suite: install what is missing, check formatting, build with warnings as
# errors, run every test through ctest in parallel, then check that gcc -O0 and clang -O2 builds
# of the engine give the main build's golden hashes at every tick (tools/determinism.sh, which
# also steps scenes and a session with the ASan+UBSan build's CLI), and that an aarch64 build
# (Debian's cross compiler, run under qemu-user) gives the golden hashes at every tick; last, the
# sanitizer builds (tools/sanitize.sh: ASan+UBSan on every test, TSan on the threaded code).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/setup.sh"
fulcrum_install_packages
fulcrum_check_format
fulcrum_build
(cd "$FULCRUM_BUILD" && ctest --output-on-failure -j "$(nproc)" --timeout 900)
bash "$FULCRUM_ROOT/tools/determinism.sh"
bash "$FULCRUM_ROOT/tools/cross_aarch64.sh"
bash "$FULCRUM_ROOT/tools/sanitize.sh"
