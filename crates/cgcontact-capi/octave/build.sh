#!/usr/bin/env bash
# Builds the Octave MEX file: bash crates/cgcontact-capi/octave/build.sh OUTDIR
# writes OUTDIR/cgcontact_whereami.mex (with cgcontact_body.m and cgcontact_gap.m), statically linked to the release build of cgcontact-capi
# (no LD_LIBRARY_PATH needed): Octave loads it with addpath(OUTDIR) alone. It builds the release
# command line too (target/release/cgcontact), which the Octave test compares with.
# Needs mkoctfile (Debian: apt-get install -y octave liboctave-dev). Honours CARGO_TARGET_DIR.
set -euo pipefail
out=${1:?usage: build.sh OUTDIR}
here=$(cd "$(dirname "$0")" && pwd)
if ! command -v mkoctfile >/dev/null; then
    echo "build.sh: mkoctfile not found; install it with: apt-get install -y octave liboctave-dev" >&2
    exit 2
fi
cd "$here/../../.."
# The command line too: test_cgcontact_whereami.m compares with it (CGCONTACT_BIN), and one cargo
# call for both unifies their dependencies' features once. `-p cgcontact-capi` alone after a
# build of both (CI's) rebuilt 13 crates with other features: 1 m 52 s on a 2-core VM.
cargo build --release --locked -p cgcontact-capi -p cgcontact-cli
target=$(cargo metadata --format-version 1 --no-deps | sed -n 's/.*"target_directory":"\([^"]*\)".*/\1/p')
lib="$target/release/libcgcontact_capi.a"
mkdir -p "$out"
# --exclude-libs keeps the Rust library's symbols private to the MEX file.
mkoctfile --mex -O2 -I"$here/../include" "$here/cgcontact_whereami.c" "$lib" \
    -Wl,--exclude-libs,ALL -lpthread -ldl -lm -o "$out/cgcontact_whereami.mex"
# The handle class that frees its body when cleared, and the gap call's wrapper.
cp "$here/cgcontact_body.m" "$here/cgcontact_gap.m" "$out/"
echo "wrote $out/cgcontact_whereami.mex, $out/cgcontact_body.m and $out/cgcontact_gap.m"
