#!/usr/bin/env bash
# A coverage-guided campaign with AFL++ on one target, for SECONDS:
#   tools/fuzz/afl/run.sh vdb|scene|render SECONDS [OUT]
# Needs `cargo install cargo-afl` once (AFL++ is built on stable Rust) and
# the main build (`cargo build --release`, for `vdbfuzz seeds`). Seeds: the
# generated grids and the real files of VDBPHOTON_REAL_DATA under AFL's
# 1 MB limit; every example scene; for renders, every example scene with
# the VDB it reads, and the cloud scene with each generated grid. Prints AFL's counts; exits 1 if AFL
# saved a crash or a hang (under OUT/default/crashes and hangs).
set -euo pipefail
target=${1:?usage: run.sh vdb|scene|render SECONDS [OUT]}
secs=${2:?usage: run.sh vdb|scene|render SECONDS [OUT]}
root=$(cd "$(dirname "$0")/../../.." && pwd)
out=${3:-$root/target/afl/$target}
case $target in vdb|scene|render) ;; *) echo "run.sh: unknown target '$target' (vdb, scene or render)" >&2; exit 2 ;; esac
command -v cargo-afl >/dev/null || { echo "run.sh: cargo-afl is missing: cargo install cargo-afl" >&2; exit 2; }

(cd "$root/tools/fuzz/afl" && cargo afl build --release --quiet)
seeds=$root/target/afl/seeds-$target
rm -rf "$seeds" && mkdir -p "$seeds"
if [ "$target" = vdb ]; then
  "$root/target/release/vdbfuzz" seeds "$seeds" >/dev/null
  data=${VDBPHOTON_REAL_DATA:-$root/../shared/data}
  if [ -d "$data" ]; then
    find "$data" -name '*.vdb' -size -1000k -not -path '*/external/*' -exec cp -t "$seeds" {} +
  fi
  find "$seeds" -size +1000k -delete
elif [ "$target" = render ]; then
  # A render input: format byte, scene text reading input.vdb, NUL, VDB.
  i=0
  seed() { # FORMAT_BYTE SCENE VDB
    { printf "$1"; sed -E 's#^( *"?file"? *[=:] *")[^"]*"#\1input.vdb"#' "$2"; printf '\x00'; cat "$3"; } > "$seeds/render$i"
    i=$((i + 1))
  }
  for f in "$root"/scenes/*.toml "$root"/scripts/cycles/*.toml "$root"/scripts/cycles/*.json "$root"/tests/data/*/*.toml; do
    file=$(sed -nE 's#^ *"?file"? *[=:] *"([^"]*)".*#\1#p' "$f" | head -1)
    vdb=$(dirname "$f")/$file
    [ -n "$file" ] && [ -f "$vdb" ] && [ "$(stat -c %s "$vdb")" -lt 900000 ] || continue
    case $f in *.json) b='\x01' ;; *) b='\x00' ;; esac
    seed "$b" "$f" "$vdb"
  done
  gen=$root/target/afl/generated
  rm -rf "$gen" && mkdir -p "$gen"
  "$root/target/release/vdbfuzz" seeds "$gen" >/dev/null
  for v in "$gen"/*.vdb; do
    [ "$(stat -c %s "$v")" -lt 900000 ] && seed '\x00' "$root/scenes/cloud.toml" "$v"
  done
else
  i=0
  for f in "$root"/scenes/*.toml "$root"/scenes/*.json "$root"/tests/data/*/*.toml "$root"/scripts/cycles/*.toml "$root"/scripts/cycles/*.json; do
    [ -e "$f" ] || continue
    case $f in *.json) b='\x01' ;; *) b='\x00' ;; esac
    { printf "$b"; cat "$f"; } > "$seeds/scene$i"
    i=$((i + 1))
  done
fi

export AFL_SKIP_CPUFREQ=1 AFL_I_DONT_CARE_ABOUT_MISSING_CRASHES=1 AFL_NO_UI=1
export AFL_TARGET_TMP=${AFL_TARGET_TMP:-/dev/shm}
mkdir -p "$out"
cargo afl fuzz -i "$seeds" -o "$out" -V "$secs" -m 4096 -t 2000 \
  "$root/tools/fuzz/afl/target/release/afl_$target" >"$out/afl.log" 2>&1 || {
  echo "run.sh: afl-fuzz failed, see $out/afl.log" >&2
  tail -20 "$out/afl.log" >&2
  exit 2
}
# The targets' scratch files (one per target process).
rm -rf "$AFL_TARGET_TMP"/afl_"$target"_*
stats=$out/default/fuzzer_stats
get() { awk -F' *: *' -v k="$1" '$1 == k { print $2 }' "$stats"; }
echo "afl $target: $(get execs_done) executions in $(get run_time) s, corpus $(get corpus_count) (from $(ls "$seeds" | wc -l) seeds), edges $(get edges_found) of $(get total_edges), crashes $(get saved_crashes), hangs $(get saved_hangs)"
[ "$(get saved_crashes)" = 0 ] && [ "$(get saved_hangs)" = 0 ]
