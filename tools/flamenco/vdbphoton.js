// SPDX-License-Identifier: MIT OR Apache-2.0
//
// Flamenco 3 job type for vdbphoton (https://flamenco.blender.org/).
//
// Install: copy this file into the `scripts/` folder next to the
// `flamenco-manager` executable (see tools/flamenco/README.md). The job type
// name is the file name with `_` turned into `-`: "vdbphoton".
// Needs Flamenco 3.6 or newer (`shellSplit()` and setting labels are 3.6).
//
// Written against Flamenco's own job compiler sources (read at
// projects.blender.org/studio/flamenco, mirrored on GitHub; 3.9-beta1):
//  - internal/manager/job_compilers/scripts/simple_blender_render.js and
//    echo_sleep_test.js: the shape of JOB_TYPE and compileJob(job).
//  - internal/manager/job_compilers/scripts.go (newGojaVM): the globals a
//    script gets: print, alert, frameChunker, frameCount,
//    formatTimestampLocal, shellSplit, and the modules author, path,
//    process. Scripts are compiled in strict mode; the job type name comes
//    from the file name (filenameToJobType).
//  - internal/manager/job_compilers/author.go: author.Task(name, type),
//    author.Command(name, parameters, totalStepCount),
//    task.addCommand(cmd), task.addDependency(task), job.addTask(task)
//    (Go methods, exposed lower-cased by goja's UncapFieldNameMapper).
//    job.addTask() stores a *copy* of the task, so every command and
//    dependency is added before the task is added to the job.
//  - internal/manager/job_compilers/js_globals.go: frameChunker(range,
//    chunkSize) returns chunks like "1-4", "9,10,20,21" and throws on an
//    empty or malformed range or a chunk size below 1; shellSplit() is
//    github.com/google/shlex's Split.
//  - internal/manager/job_compilers/job_compilers.go: job.settings holds the
//    submitted settings as they are; the Manager applies no defaults and
//    checks no `required` flags (the Blender add-on sends every setting, an
//    API client may not), so this script does both itself.
//  - internal/manager/api_impl/jobs.go: two-way variables are substituted
//    in string settings before compiling (/mnt/render/x -> {render}/x), so
//    paths may begin with a `{variable}`.
//  - internal/worker/command_exec.go, command_blender.go, cmd_executor.go:
//    `exec` takes {exe, args} and runs exe args...; `blender-render` takes
//    {exe, exeArgs, argsBefore, blendfile, args} and runs
//    exe exeArgs... argsBefore... blendfile args... . Only `blender-render`
//    reads the output for `Saved: '...'` lines and sends the image as the
//    job's last-rendered preview (PNG, JPEG and TIFF decode; EXR does not).
//  - internal/worker/config.go: workers run only the task types in their
//    `task_types` (default blender, ffmpeg, file-management, misc), so
//    workers need "vdbphoton" added (README).

const JOB_TYPE = {
    label: "vdbphoton Volume Render",
    description: "Render an OpenVDB volume sequence with vdbphoton, optionally as tiles merged per frame",
    settings: [
        { key: "vdbphoton_exe", label: "vdbphoton Executable", type: "string", required: true, default: "vdbphoton",
          description: "vdbphoton on the workers: a name found on their PATH, an absolute path, or a Flamenco variable such as {vdbphoton}" },
        { key: "scene", label: "Scene File", type: "string", subtype: "file_path", required: true,
          description: "The vdbphoton scene (.toml or .json) on shared storage, as an absolute path the workers can read" },
        { key: "frames", label: "Frames", type: "string", required: true,
          eval: "f'{C.scene.frame_start}-{C.scene.frame_end}'",
          evalInfo: {
            showLinkButton: true,
            description: "Scene frame range",
          },
          description: "Frames to render, in Flamenco's notation. Examples: '47', '1-40', '1-10,20-30', '1001-1100'" },
        { key: "chunk_size", label: "Chunk Size", type: "int32", default: 1, propargs: {min: 1},
          description: "Number of frames one render task renders (ignored when rendering tiles: then each task is one tile of one frame)" },
        { key: "output", label: "Output", type: "string", subtype: "file_path", required: true,
          description: "Output EXR per frame, with a frame pattern: {frame:04} (zero-padded), {frame} or ####. Example: /render/shot/smoke_{frame:04}.exr" },
        { key: "preview", label: "PNG Previews", type: "bool", default: true,
          description: "Also write a PNG preview per frame, next to the EXR with the .png extension" },
        { key: "tiles", label: "Tiles per Frame", type: "int32", default: 0, propargs: {min: 0, max: 1024},
          description: "0 or 1: render whole frames. N > 1: render each frame as N tiles (one task each, into a 'tiles' folder beside the output), then merge them in one task per frame" },
        { key: "skip_existing", label: "Skip Existing", type: "bool", default: true,
          description: "Skip frames (and tiles) whose EXR already exists, so that requeued tasks do not redo finished work" },
        { key: "resume", label: "Resume Requeued Tasks", type: "bool", default: true,
          description: "Render tasks checkpoint every 60 s (unless Extra Render Arguments give --checkpoint) and a requeued or restarted task resumes from its own last checkpoint (--resume), to the same pixels as an undisturbed task" },
        { key: "extra_args", label: "Extra Render Arguments", type: "string", default: "",
          description: "More vdbphoton render options, split like a shell command line. Example: --spp 512 --view agx" },
        { key: "merge_args", label: "Extra Merge Arguments", type: "string", default: "",
          description: "More vdbphoton merge options for tiled renders. Example: --exposure 0.5 --view agx" },
        { key: "flamenco_previews", label: "Previews in Flamenco", type: "bool", default: true,
          description: "Run vdbphoton through Flamenco's blender-render worker command, the only one that shows the Saved: images as the job's last-rendered preview; off: the plain exec command" },
    ]
};

// All tasks get this type; workers must list it in `task_types`.
const TASK_TYPE = "vdbphoton";

// vdbphoton's limits (src/sequence.rs): frame numbers go up to 9,999,999.
const MAX_FRAME = 9999999;
const MAX_TILES = 1024;

// Options the job type sets itself, so extra arguments must not repeat them
// (the CLI refuses an option given twice).
const RENDER_OPTIONS_SET_HERE = ["-o", "--output", "--frames", "--frame", "--tile", "--preview", "--no-preview", "--skip-existing", "--resume"];
const MERGE_OPTIONS_SET_HERE = ["--preview"];

function compileJob(job) {
    const settings = job.settings;
    const s = readSettings(settings);

    const frames = explodeFrames(s.frames);
    const tiled = s.tiles > 1;
    checkOutputPattern(s.output, frames.length);

    const extraArgs = splitArgs("extra_args", s.extra_args, RENDER_OPTIONS_SET_HERE.concat(tiled ? ["--region"] : []));
    const mergeArgs = splitArgs("merge_args", s.merge_args, MERGE_OPTIONS_SET_HERE);

    print(`vdbphoton job "${job.name}": ${frames.length} frame(s) of ${s.scene}` +
          (tiled ? ` as ${s.tiles} tiles each` : ` in chunks of ${s.chunk_size}`));

    if (tiled) {
        if (s.chunk_size > 1) {
            print(`chunk_size ${s.chunk_size} is ignored with tiles: each task renders one tile of one frame`);
        }
        for (const frame of frames) {
            authorTiledFrame(job, s, frame, extraArgs, mergeArgs);
        }
    } else {
        authorChunkTasks(job, s, extraArgs);
    }
}

// ---------------------------------------------------------------- settings

// Returns the settings with JOB_TYPE's defaults filled in and their types
// checked; throws a message naming the setting otherwise.
function readSettings(settings) {
    const s = {};
    for (const def of JOB_TYPE.settings) {
        let value = settings[def.key];
        if (value === undefined || value === null) {
            if (def.default !== undefined) {
                value = def.default;
            } else if (def.required) {
                throw `vdbphoton: the setting "${def.key}" is required (${def.description})`;
            } else {
                continue;
            }
        }
        switch (def.type) {
        case "string":
            if (typeof value !== "string") {
                throw `vdbphoton: the setting "${def.key}" must be a string, not ${JSON.stringify(value)}`;
            }
            if (def.required && value.trim() === "") {
                throw `vdbphoton: the setting "${def.key}" is empty (${def.description})`;
            }
            break;
        case "int32":
            if (typeof value !== "number" || !Number.isInteger(value)) {
                throw `vdbphoton: the setting "${def.key}" must be a whole number, not ${JSON.stringify(value)}`;
            }
            break;
        case "bool":
            if (typeof value !== "boolean") {
                throw `vdbphoton: the setting "${def.key}" must be true or false, not ${JSON.stringify(value)}`;
            }
            break;
        }
        s[def.key] = value;
    }

    s.vdbphoton_exe = s.vdbphoton_exe.trim();
    s.scene = s.scene.trim();
    s.output = s.output.trim();
    if (s.chunk_size < 1) {
        throw `vdbphoton: chunk_size must be at least 1 (frames per render task), not ${s.chunk_size}`;
    }
    if (s.tiles < 0 || s.tiles > MAX_TILES) {
        throw `vdbphoton: tiles must be 0 or 1 (no tiling) or 2 to ${MAX_TILES} (tiles per frame), not ${s.tiles}`;
    }
    checkFarmPath("scene", s.scene);
    checkFarmPath("output", s.output);
    return s;
}

// Workers run in their own working folders, so paths must be absolute, or
// begin with a Flamenco variable (two-way variables turn /mnt/render/x into
// {render}/x before the job is compiled).
function checkFarmPath(key, p) {
    if (!/^(\/|\\|[A-Za-z]:[\\/]|\{[^{}]+\})/.test(p)) {
        throw `vdbphoton: the ${key} path "${p}" is relative; give an absolute path on shared storage (every worker must see it at that path, or through a Flamenco variable)`;
    }
}

// Splits an arguments setting with Flamenco's shellSplit() and refuses the
// options the job type sets itself.
function splitArgs(key, text, forbidden) {
    if (text.trim() === "") {
        return [];
    }
    let args;
    try {
        args = Array.from(shellSplit(text));
    } catch (e) {
        throw `vdbphoton: ${key} "${text}" cannot be split into arguments: ${errorText(e)}`;
    }
    for (const a of args) {
        for (const opt of forbidden) {
            const short = opt.length === 2;
            if (a === opt || a.startsWith(opt + "=") || (short && a.startsWith(opt))) {
                throw `vdbphoton: ${key} must not contain ${opt}: the job type sets it from its own settings`;
            }
        }
    }
    return args;
}

// The message of something thrown by a Go function: goja throws a GoError
// (an Error with .message) for returned errors, and shellSplit throws the Go
// error value itself (whose string form is the message).
function errorText(e) {
    if (e !== null && typeof e === "object" && typeof e.message === "string") {
        return e.message;
    }
    return String(e);
}

// ------------------------------------------------------------------ frames

// The frames of `range` (Flamenco's notation), ascending, checked against
// vdbphoton's limits.
function explodeFrames(range) {
    let single;
    try {
        single = frameChunker(range, 1);
    } catch (e) {
        let hint = "write frames like 47, 1-40 or 1-10,20-30";
        if (/:/.test(range)) {
            hint = "Flamenco frame ranges have no :STEP, " + hint;
        }
        throw `vdbphoton: frames "${range}" is not a frame range (${hint}): ${errorText(e)}`;
    }
    const frames = [];
    for (const f of single) {
        const n = Number(f);
        if (!Number.isInteger(n) || n < 0 || n > MAX_FRAME) {
            throw `vdbphoton: frame ${f} in "${range}" is out of range: vdbphoton frames go from 0 to ${MAX_FRAME}`;
        }
        frames.push(n);
    }
    return frames;
}

// --------------------------------------------------------- path patterns

// A port of vdbphoton's frame patterns (src/sequence.rs, `fields`):
// `{frame}`, `{frame:04}` / `{frame:4}` (zero-padded, 1 to 10 digits), a run
// of `#` (padded to its length), and `{tile}`. Other `{frame...}` or
// `{tile...}` forms are errors; other braces (Flamenco variables) are text.
// Returns a list of {kind: "text"|"frame"|"tile", pad, text}.
function patternFields(s) {
    const out = [];
    let rest = s;
    while (rest.length > 0) {
        const brace = rest.indexOf("{");
        const hash = rest.indexOf("#");
        let at;
        if (brace >= 0 && hash >= 0) {
            at = Math.min(brace, hash);
        } else if (brace >= 0) {
            at = brace;
        } else if (hash >= 0) {
            at = hash;
        } else {
            out.push({kind: "text", text: rest});
            break;
        }
        if (at > 0) {
            out.push({kind: "text", text: rest.slice(0, at)});
            rest = rest.slice(at);
            continue;
        }
        if (rest[0] === "#") {
            let n = 0;
            while (n < rest.length && rest[n] === "#") {
                n++;
            }
            out.push({kind: "frame", pad: n, text: rest.slice(0, n)});
            rest = rest.slice(n);
            continue;
        }
        const close = rest.indexOf("}");
        if (close < 0) {
            out.push({kind: "text", text: rest});
            break;
        }
        const inner = rest.slice(1, close);
        const text = rest.slice(0, close + 1);
        if (inner === "frame") {
            out.push({kind: "frame", pad: 0, text: text});
        } else if (inner.startsWith("frame:")) {
            const spec = inner.slice("frame:".length);
            const digits = spec.startsWith("0") ? spec.slice(1) : spec;
            const pad = /^[0-9]+$/.test(digits) ? Number(digits) : NaN;
            if (!(pad >= 1 && pad <= 10)) {
                throw `vdbphoton: '{${inner}}' in '${s}' is not a frame pattern: write {frame}, {frame:04} (zero-padded to 4 digits) or ####`;
            }
            out.push({kind: "frame", pad: pad, text: text});
        } else if (inner === "tile") {
            out.push({kind: "tile", text: text});
        } else if (inner.startsWith("frame") || inner.startsWith("tile")) {
            throw `vdbphoton: '{${inner}}' in '${s}' is not a pattern: write {frame}, {frame:04}, #### or {tile}`;
        } else {
            out.push({kind: "text", text: text});
        }
        rest = rest.slice(close + 1);
    }
    return out;
}

// The path of `frame`, as vdbphoton would write it.
function expandFrame(pattern, frame) {
    return patternFields(pattern).map((f) => {
        if (f.kind === "frame") {
            return String(frame).padStart(f.pad, "0");
        }
        return f.text;
    }).join("");
}

function checkOutputPattern(output, frameCount) {
    const fields = patternFields(output);
    if (!/\.exr$/i.test(output)) {
        throw `vdbphoton: output "${output}" must end in .exr (vdbphoton writes OpenEXR)`;
    }
    if (fields.some((f) => f.kind === "tile")) {
        throw `vdbphoton: output "${output}" must not hold {tile}: set "tiles" instead, the job type names the tile files itself`;
    }
    if (frameCount > 1 && !fields.some((f) => f.kind === "frame")) {
        throw `vdbphoton: output "${output}" has no frame pattern, so all ${frameCount} frames would overwrite one file; add {frame:04}, {frame} or ####`;
    }
}

// The PNG preview beside an EXR: same path, .png extension.
function previewOf(exrPath) {
    return exrPath.replace(/\.exr$/i, ".png");
}

// ----------------------------------------------------------------- tasks

// With `resume`: checkpoints (every 60 s unless the extra arguments set
// --checkpoint) and --resume, so a task Flamenco requeues (a worker lost, a
// task requeued by hand) goes on from its own last checkpoint.
function resumeArgs(s, extraArgs) {
    if (!s.resume) return [];
    const ownCheckpoint = extraArgs.some((a) => a === "--checkpoint" || a.startsWith("--checkpoint="));
    return (ownCheckpoint ? [] : ["--checkpoint", "60s"]).concat(["--resume"]);
}

// One render task per chunk of frames. The output keeps its frame pattern:
// vdbphoton expands it per frame.
function authorChunkTasks(job, s, extraArgs) {
    const chunks = frameChunker(s.frames, s.chunk_size);
    for (const chunk of chunks) {
        const task = author.Task(`render-${chunk}`, TASK_TYPE);
        const args = ["--frames", chunk, "-o", s.output]
            .concat(s.preview ? ["--preview", previewOf(s.output)] : ["--no-preview"])
            .concat(s.skip_existing ? ["--skip-existing"] : [])
            .concat(resumeArgs(s, extraArgs))
            .concat(extraArgs);
        task.addCommand(vdbphotonCommand(s, "render", s.scene, args));
        job.addTask(task);
    }
}

// N tile tasks for one frame, then a merge task that depends on exactly
// those. Tile paths are spelled out here (not left to {tile}) so the merge
// reads exactly the files the tile tasks write, and so no Flamenco variable
// named "tile" can change them.
function authorTiledFrame(job, s, frame, extraArgs, mergeArgs) {
    const out = expandFrame(s.output, frame);
    const tileDir = path.join(path.dirname(out), "tiles");
    const tileTasks = [];
    const tilePaths = [];
    for (let i = 0; i < s.tiles; i++) {
        const tilePath = path.join(tileDir, `${path.stem(out)}_tile${i}of${s.tiles}.exr`);
        const task = author.Task(`render-${frame}-tile-${i}of${s.tiles}`, TASK_TYPE);
        const args = ["--frame", String(frame), "--tile", `${i}/${s.tiles}`, "-o", tilePath, "--no-preview"]
            .concat(s.skip_existing ? ["--skip-existing"] : [])
            .concat(resumeArgs(s, extraArgs))
            .concat(extraArgs);
        task.addCommand(vdbphotonCommand(s, "render", s.scene, args));
        job.addTask(task);
        tileTasks.push(task);
        tilePaths.push(tilePath);
    }

    const merge = author.Task(`merge-${frame}`, TASK_TYPE);
    const args = tilePaths
        .concat(s.preview ? ["--preview", previewOf(out)] : [])
        .concat(mergeArgs);
    merge.addCommand(vdbphotonCommand(s, "merge", out, args));
    for (const t of tileTasks) {
        merge.addDependency(t);
    }
    // Added last: job.addTask() copies the task as it is now.
    job.addTask(merge);
}

// The command that runs `vdbphoton SUBCOMMAND FIRST ARGS...` on a worker.
// Both forms run the same argv; `blender-render` builds it as
// exe, exeArgs, argsBefore, blendfile, args (command_blender.go) and
// forwards `Saved: '...'` lines as previews, `exec` does not.
function vdbphotonCommand(s, subcommand, first, args) {
    if (s.flamenco_previews) {
        return author.Command("blender-render", {
            exe: s.vdbphoton_exe,
            exeArgs: "",
            argsBefore: [subcommand],
            blendfile: first,
            args: args,
        });
    }
    return author.Command("exec", {
        exe: s.vdbphoton_exe,
        args: [subcommand, first].concat(args),
    });
}
