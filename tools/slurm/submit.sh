#!/usr/bin/env bash
# Submits vdbphoton renders to Slurm and prints the job ids.
#
#   tools/slurm/submit.sh frames SCENE.toml LIST [OPTIONS] [-- RENDER ARGS...]
#       One array task per frame of LIST (`1001-1100`, `1-3,5,7-20:2`), each
#       running `vdbphoton render SCENE --frame F [RENDER ARGS...]`.
#       Prints `frames JOBID` (one line per array; a list spanning more than
#       Slurm's MaxArraySize frames is split into several arrays).
#
#   tools/slurm/submit.sh tile SCENE.toml FRAME N OUT.exr [OPTIONS] [-- RENDER ARGS...]
#       Frame FRAME (`-` for a scene without a frame pattern) in N tiles, one
#       array task each (`--tile I/N`, into OUT's tiles folder), then a merge
#       job (afterok on every tile, --kill-on-invalid-dep=yes) writing OUT.exr.
#       Prints `tiles JOBID` and `merge JOBID`.
#
# Options:
#   -p, --partition P       Slurm partition
#   -r, --max-running N     at most N tasks of an array running at once (--array=...%N)
#   --vdbphoton PATH        the vdbphoton binary, on storage every node sees
#                           (default: $VDBPHOTON, else vdbphoton on PATH)
#   --skip-existing         frames (and tiles) whose EXR exists are not rendered again;
#                           with `tile`, nothing is submitted when OUT.exr exists
#   -c, --cpus-per-task N   CPUs per task (the render uses them all)
#   --mem SIZE              memory per task (Slurm's --mem, e.g. 16G)
#   -t, --time LIMIT        time limit per task (Slurm's --time, e.g. 2:00:00)
#   --logs DIR              job logs (default: ./slurm-logs), %x-%A_%a.out
#   --name NAME             job name prefix (default: vdbphoton): NAME-frames, NAME-tiles, NAME-merge
#   --sbatch ARG            pass ARG to every sbatch (repeatable): --sbatch=--account=fx
#   --tiles-dir DIR         (tile) where tiles go (default: OUT without .exr, plus .tiles)
#   --preview PNG           (tile) the merge also writes this PNG preview
#   --merge-arg ARG         (tile) pass ARG to vdbphoton merge (repeatable): --merge-arg=--view=agx
#   -n, --dry-run           print the sbatch commands instead of running them
#
# Paths (scene, outputs, logs, vdbphoton) are made absolute here; every node
# must see them at the same paths (shared storage). Job scripts: frames.sbatch,
# tiles.sbatch, merge.sbatch beside this file.
#
# Preemption: the render tasks are requeueable (--requeue), get SIGTERM 60 s
# before their time limit (--signal=B:TERM@60), and render with
# --checkpoint 60s --resume (a --checkpoint among the RENDER ARGS sets the
# interval), so a preempted or requeued task (`scontrol requeue ID`) goes on
# from its own last checkpoint to the same pixels (tools/slurm/README.md).
set -euo pipefail

HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
me=submit.sh

usage() {
    sed -n '2,42p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'
    exit 2
}
die() {
    echo "$me: $*" >&2
    exit 2
}

[ $# -ge 1 ] || usage
mode=$1
shift
case $mode in
frames | tile) ;;
-h | --help) usage ;;
*) die "unknown mode '$mode' (frames or tile)" ;;
esac

partition=""
max_running=""
vdbphoton=${VDBPHOTON:-}
skip=0
cpus=""
mem=""
timelimit=""
logs=slurm-logs
name=vdbphoton
tiles_dir=""
preview=""
dry=0
sbatch_extra=()
merge_extra=()
render_args=()
pos=()

need_val() { [ $# -ge 2 ] || die "$1 needs a value"; }
while [ $# -gt 0 ]; do
    case $1 in
    --) shift; render_args=("$@"); break ;;
    -p | --partition) need_val "$@"; partition=$2; shift 2 ;;
    --partition=*) partition=${1#*=}; shift ;;
    -r | --max-running) need_val "$@"; max_running=$2; shift 2 ;;
    --max-running=*) max_running=${1#*=}; shift ;;
    --vdbphoton) need_val "$@"; vdbphoton=$2; shift 2 ;;
    --vdbphoton=*) vdbphoton=${1#*=}; shift ;;
    --skip-existing) skip=1; shift ;;
    -c | --cpus-per-task) need_val "$@"; cpus=$2; shift 2 ;;
    --cpus-per-task=*) cpus=${1#*=}; shift ;;
    --mem) need_val "$@"; mem=$2; shift 2 ;;
    --mem=*) mem=${1#*=}; shift ;;
    -t | --time) need_val "$@"; timelimit=$2; shift 2 ;;
    --time=*) timelimit=${1#*=}; shift ;;
    --logs) need_val "$@"; logs=$2; shift 2 ;;
    --logs=*) logs=${1#*=}; shift ;;
    --name) need_val "$@"; name=$2; shift 2 ;;
    --name=*) name=${1#*=}; shift ;;
    --sbatch) need_val "$@"; sbatch_extra+=("$2"); shift 2 ;;
    --sbatch=*) sbatch_extra+=("${1#*=}"); shift ;;
    --tiles-dir) need_val "$@"; tiles_dir=$2; shift 2 ;;
    --tiles-dir=*) tiles_dir=${1#*=}; shift ;;
    --preview) need_val "$@"; preview=$2; shift 2 ;;
    --preview=*) preview=${1#*=}; shift ;;
    --merge-arg) need_val "$@"; merge_extra+=("$2"); shift 2 ;;
    --merge-arg=*) merge_extra+=("${1#*=}"); shift ;;
    -n | --dry-run) dry=1; shift ;;
    -h | --help) usage ;;
    -?*) die "unknown option '$1' (vdbphoton's own options go after --)" ;;
    *) pos+=("$1"); shift ;;
    esac
done

if [ -n "$max_running" ]; then
    case $max_running in '' | *[!0-9]* | 0) die "--max-running must be a positive number, not '$max_running'" ;; esac
fi

# The binary, as an absolute path the job scripts can run on any node.
if [ -z "$vdbphoton" ]; then
    vdbphoton=$(command -v vdbphoton || true)
    [ -n "$vdbphoton" ] || die "vdbphoton is not on PATH: give its path with --vdbphoton (or \$VDBPHOTON)"
fi
case $vdbphoton in
*/*) vdbphoton=$(realpath -m -- "$vdbphoton") ;;
*) vdbphoton=$(command -v -- "$vdbphoton" || true) ;;
esac
if [ -z "$vdbphoton" ] || [ ! -x "$vdbphoton" ] || [ -d "$vdbphoton" ]; then
    die "vdbphoton binary not found or not executable: '${vdbphoton:-(none)}'"
fi

common=(--parsable)
[ -n "$partition" ] && common+=(--partition "$partition")
[ -n "$cpus" ] && common+=(--cpus-per-task "$cpus")
[ -n "$mem" ] && common+=(--mem "$mem")
[ -n "$timelimit" ] && common+=(--time "$timelimit")
common+=("${sbatch_extra[@]}")

logs=$(realpath -m -- "$logs")
if [ "$dry" = 0 ]; then
    mkdir -p -- "$logs" || die "cannot create the log folder '$logs'"
fi

# Runs sbatch (or prints it with --dry-run) and prints the job id.
submitted=()
submit() {
    local out
    if [ "$dry" = 1 ]; then
        printf '%q ' sbatch "$@" >&2
        echo >&2
        echo "DRYRUN$((${#submitted[@]} + 1))"
        return 0
    fi
    if ! out=$(sbatch "$@"); then
        echo "$me: sbatch failed: sbatch $*" >&2
        return 1
    fi
    echo "${out%%;*}"
}
cancel_submitted() {
    if [ "$dry" = 0 ] && [ ${#submitted[@]} -gt 0 ]; then
        echo "$me: cancelling the jobs already submitted: ${submitted[*]}" >&2
        scancel "${submitted[@]}" || true
    fi
}

# Expands a frame list (`1001-1100`, `1-3,5,7-20:2`) to sorted unique frames.
expand_frames() {
    local item a b s
    local IFS=,
    for item in $1; do
        if [[ $item =~ ^([0-9]+)$ ]]; then
            echo "$((10#${BASH_REMATCH[1]}))"
        elif [[ $item =~ ^([0-9]+)-([0-9]+)(:([0-9]+))?$ ]]; then
            a=$((10#${BASH_REMATCH[1]}))
            b=$((10#${BASH_REMATCH[2]}))
            s=$((10#${BASH_REMATCH[4]:-1}))
            [ "$b" -ge "$a" ] || die "frame range '$item' ends before it starts"
            [ "$s" -ge 1 ] || die "frame range '$item' has a step of 0"
            [ $(((b - a) / s)) -lt 100000 ] || die "frame range '$item' has over 100000 frames"
            seq "$a" "$s" "$b"
        else
            die "bad frame list item '$item' in '$1' (use N, A-B or A-B:STEP, separated by commas)"
        fi
    done | sort -n -u
}

# Offsets (sorted) -> a Slurm array spec: runs with a constant step as A-B:S.
array_spec() {
    awk '{ o[n++] = $1 }
    END {
        spec = ""; i = 0
        while (i < n) {
            item = o[i]
            if (i + 1 < n) {
                step = o[i + 1] - o[i]; j = i + 1
                while (j + 1 < n && o[j + 1] - o[j] == step) j++
                if (step == 1 || j - i >= 2) {
                    item = o[i] "-" o[j] (step > 1 ? ":" step : "")
                    i = j + 1
                } else i++
            } else i++
            spec = spec (spec == "" ? "" : ",") item
        }
        print spec
    }'
}

if [ "$mode" = frames ]; then
    [ ${#pos[@]} -eq 2 ] || die "usage: submit.sh frames SCENE LIST [OPTIONS] [-- RENDER ARGS...]"
    scene=$(realpath -m -- "${pos[0]}")
    list=${pos[1]}
    [ -f "$scene" ] || die "scene file not found: '${pos[0]}'"
    frames=$(expand_frames "$list")
    [ -n "$frames" ] || die "the frame list '$list' is empty"

    # Array indices must stay below MaxArraySize (1001 by default).
    max_array=""
    if [ "$dry" = 0 ]; then
        max_array=$(scontrol show config 2>/dev/null | awk '$1 == "MaxArraySize" { print $3 }')
    fi
    case $max_array in '' | *[!0-9]*) max_array=1001 ;; esac

    args=()
    [ "$skip" = 1 ] && args+=(--skip-existing)
    args+=("${render_args[@]}")

    # Chunks of frames F with F - base < MaxArraySize, each one array job.
    chunks=$(awk -v m="$max_array" '
        NR == 1 || $1 - base >= m { base = $1; printf "%s%s", (NR == 1 ? "" : "\n"), base }
        { printf " %d", $1 - base }
        END { print "" }' <<<"$frames")
    while read -r base offsets; do
        spec=$(tr ' ' '\n' <<<"$offsets" | array_spec)
        count=$(wc -w <<<"$offsets")
        first=$((base + ${offsets%% *}))
        last=$((base + ${offsets##* }))
        [ -n "$max_running" ] && spec="$spec%$max_running"
        if ! id=$(submit "${common[@]}" --job-name "$name-frames" --array "$spec" \
            --output "$logs/%x-%A_%a.out" \
            "$HERE/frames.sbatch" --base "$base" --vdbphoton "$vdbphoton" "$scene" "${args[@]}"); then
            cancel_submitted
            exit 1
        fi
        submitted+=("$id")
        echo "$me: frames $first-$last ($count frames, base $base, --array $spec): job $id, logs $logs/$name-frames-${id}_*.out" >&2
        echo "frames $id"
    done <<<"$chunks"
    exit 0
fi

# tile
[ ${#pos[@]} -eq 4 ] || die "usage: submit.sh tile SCENE FRAME N OUT.exr [OPTIONS] [-- RENDER ARGS...]"
scene=$(realpath -m -- "${pos[0]}")
frame=${pos[1]}
n=${pos[2]}
out=$(realpath -m -- "${pos[3]}")
[ -f "$scene" ] || die "scene file not found: '${pos[0]}'"
case $frame in
-) frame_args=() ;;
'' | *[!0-9]*) die "FRAME must be a frame number or '-', not '$frame'" ;;
*) frame_args=(--frame "$((10#$frame))") ;;
esac
case $n in
'' | *[!0-9]* | 0) die "N (the tile count) must be a positive number, not '$n'" ;;
esac
case $out in
*.exr) ;;
*) die "the output must end in .exr: '${pos[3]}'" ;;
esac
if [ "$skip" = 1 ] && [ -f "$out" ]; then
    echo "$me: $out exists: nothing submitted (--skip-existing)" >&2
    exit 0
fi
[ -n "$tiles_dir" ] || tiles_dir=${out%.exr}.tiles
tiles_dir=$(realpath -m -- "$tiles_dir")
pattern="$tiles_dir/tile_{tile}.exr"

args=()
[ "$skip" = 1 ] && args+=(--skip-existing)
args+=("${render_args[@]}")
spec="0-$((n - 1))"
[ -n "$max_running" ] && spec="$spec%$max_running"

tiles_id=$(submit "${common[@]}" --job-name "$name-tiles" --array "$spec" \
    --output "$logs/%x-%A_%a.out" \
    "$HERE/tiles.sbatch" "${frame_args[@]}" --vdbphoton "$vdbphoton" "$scene" "$n" "$pattern" "${args[@]}") || exit 1
submitted+=("$tiles_id")

margs=()
[ -n "$preview" ] && margs+=(--preview "$(realpath -m -- "$preview")")
margs+=("${merge_extra[@]}")
if ! merge_id=$(submit "${common[@]}" --job-name "$name-merge" \
    --dependency "afterok:$tiles_id" --kill-on-invalid-dep=yes \
    --output "$logs/%x-%j.out" \
    "$HERE/merge.sbatch" --vdbphoton "$vdbphoton" "$out" "$n" "$pattern" "${margs[@]}"); then
    cancel_submitted
    exit 1
fi
what="frame $frame"
[ "$frame" = - ] && what="the frame"
echo "$me: $what in $n tiles ($tiles_dir): job $tiles_id; merge into $out: job $merge_id (after all tiles succeed); logs in $logs" >&2
echo "tiles $tiles_id"
echo "merge $merge_id"
