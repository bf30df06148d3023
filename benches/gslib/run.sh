#!/usr/bin/env bash
# gslib findpts against cgcontact's lattice locator on the same indented blocks (docs/gslib.md).
#
# Usage: GSLIB_DIR=/tmp/gslib benches/gslib/run.sh [NX ...]
#
#   GSLIB_DIR   a gslib checkout built serial: make MPI=0 CC=gcc CFLAGS="-O2 -march=native" lib install
#   DATA_DIR    where the binaries go (default /tmp/cgcontact-gslib); each size's are removed after
#               its run unless KEEP=1
#   POINTS      known points per block (default 1000000); SEED (default 7); REPEATS (default 3)
#   CARGO_TARGET_DIR  as usual (default target)
#   EXPORT_BIN  an already built export_block to use instead of building it with cargo
#   NX ...      blocks NX × 2NX × NX (default 20 40 80 128: 16,000 to 4,194,304 cells)
#
# For each size, one after the other (never two big jobs at once): export the scene, gslib setup
# and findpts (one thread), then cgcontact's lattice locator on a one-thread pool, same scene.
set -euo pipefail

: "${GSLIB_DIR:?set GSLIB_DIR to a serial gslib build (see docs/gslib.md)}"
DATA_DIR=${DATA_DIR:-/tmp/cgcontact-gslib}
POINTS=${POINTS:-1000000}
SEED=${SEED:-7}
REPEATS=${REPEATS:-3}
SIZES=("$@")
if [ ${#SIZES[@]} -eq 0 ]; then SIZES=(20 40 80 128); fi

ROOT=$(cd "$(dirname "$0")/../.." && pwd)
TARGET=${CARGO_TARGET_DIR:-$ROOT/target}
CC=${CC:-gcc}
CFLAGS=${CFLAGS:-"-O2 -march=native"}

if [ ! -f "$GSLIB_DIR/build/lib/libgs.a" ] || [ ! -f "$GSLIB_DIR/build/include/gslib/config.h" ]; then
  echo "no $GSLIB_DIR/build/lib/libgs.a or build/include/gslib/config.h: build gslib first" >&2
  exit 1
fi
if grep -q GSLIB_USE_MPI "$GSLIB_DIR/build/include/gslib/config.h"; then
  echo "gslib in $GSLIB_DIR was built with MPI; rebuild it with MPI=0" >&2
  exit 1
fi

mkdir -p "$DATA_DIR"
BENCH="$DATA_DIR/findpts_bench"
# shellcheck disable=SC2086
"$CC" $CFLAGS -I"$GSLIB_DIR/build/include/gslib" -I"$GSLIB_DIR/src" \
  "$ROOT/benches/gslib/findpts_bench.c" "$GSLIB_DIR/build/lib/libgs.a" -lm -o "$BENCH"
if [ -n "${EXPORT_BIN:-}" ]; then
  EXPORT=$EXPORT_BIN
else
  (cd "$ROOT" && CARGO_TARGET_DIR="$TARGET" cargo build --release -q -p cgcontact-benches --example export_block)
  EXPORT="$TARGET/release/examples/export_block"
fi

echo "# $(date -u +%FT%TZ) $(uname -n) $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), $(nproc) cores"
echo "# cgcontact tree $(git -C "$ROOT" rev-parse --short HEAD)$(git -C "$ROOT" diff --quiet HEAD -- crates benches || echo ' (dirty tree)'), export_block $EXPORT"
if [ -d "$GSLIB_DIR/.git" ]; then echo "# gslib $(git -C "$GSLIB_DIR" rev-parse --short HEAD)"; fi
echo "# points=$POINTS seed=$SEED repeats=$REPEATS cc='$CC $CFLAGS'"
for nx in "${SIZES[@]}"; do
  dir="$DATA_DIR/block-$nx"
  echo "## block $nx x $((2 * nx)) x $nx"
  "$EXPORT" "$nx" $((2 * nx)) "$nx" "$POINTS" "$SEED" "$dir"
  /usr/bin/time -f "gslib process: %e s wall, max RSS %M KiB" "$BENCH" "$dir" "$REPEATS"
  "$EXPORT" "$nx" $((2 * nx)) "$nx" "$POINTS" "$SEED" --measure
  if [ "${KEEP:-0}" != 1 ]; then rm -rf "$dir"; fi
done
