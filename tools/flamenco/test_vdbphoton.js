#!/usr/bin/env node
// SPDX-License-Identifier: MIT OR Apache-2.0
//
// Test harness for the Flamenco job type tools/flamenco/vdbphoton.js.
//
//     node tools/flamenco/test_vdbphoton.js
//
// Plain Node (no npm packages). It loads vdbphoton.js into a fresh
// `node:vm` context per compiled job, the way Flamenco Manager gives each
// compile a fresh goja VM, with stubs of everything Flamenco's runtime gives
// a job compiler script, ported from Flamenco's Go sources (3.9-beta1):
//
//   internal/manager/job_compilers/scripts.go     newGojaVM(): the globals
//   internal/manager/job_compilers/author.go      author.Task/Command, addTask...
//   internal/manager/job_compilers/js_globals.go  frameChunker, frameCount,
//                                                 shellSplit, formatTimestampLocal
//   internal/manager/job_compilers/js_path.go +   the `path` module
//     pkg/crosspath/crosspath.go
//   internal/manager/job_compilers/js_process.go  the `process` module
//   github.com/google/shlex (e7afc7fbc510)        what shellSplit() runs
//   internal/worker/command_exec.go,              how a worker turns a command
//     command_blender.go, cmd_executor.go         into an argv
//   internal/manager/persistence/jobs.go          dependencies must be tasks
//                                                 of the same job; commands
//                                                 are stored as JSON
//   pkg/api/flamenco-openapi.yaml                 AvailableJobSetting schema
//
// The stubs are themselves checked against the cases of Flamenco's own Go
// unit tests (js_globals_test.go, crosspath_test.go).
//
// Exit status 0 and "N checks passed" when everything passes; 1 otherwise.

"use strict";

const fs = require("node:fs");
const nodePath = require("node:path");
const vm = require("node:vm");
const assert = require("node:assert/strict");

const SCRIPT = nodePath.join(__dirname, "vdbphoton.js");

// ===================================================================
// Stubs of Flamenco's job compiler runtime
// ===================================================================

// goja turns an `error` returned by a Go function into a thrown GoError: an
// Error whose message is err.Error() (goja Runtime.NewGoError).
function goError(message) {
    const e = new Error(message);
    e.name = "GoError";
    return e;
}

// goja converts a JS argument for a Go `string` parameter with ToString, and
// fills missing arguments with Go's zero value.
function goString(v) {
    return v === undefined || v === null ? "" : String(v);
}

// ... and for a Go `int` parameter with ToInteger (NaN -> 0, truncation).
function goInt(v) {
    if (v === undefined || v === null) return 0;
    const n = Number(v);
    return Number.isFinite(n) ? Math.trunc(n) : 0;
}

// Go's strconv.ParseInt(s, 10, 64) after strings.TrimSpace, returning
// [value, errorString|null].
function parseInt64(s) {
    const t = s.trim();
    const q = JSON.stringify(t); // strconv.Quote, for the ASCII cases used here
    if (!/^[+-]?[0-9]+$/.test(t)) {
        return [0, `strconv.ParseInt: parsing ${q}: invalid syntax`];
    }
    const big = BigInt(t);
    if (big > 9223372036854775807n || big < -9223372036854775808n) {
        return [0, `strconv.ParseInt: parsing ${q}: value out of range`];
    }
    return [Number(big), null];
}

// ErrInvalidRange.Error() (js_globals.go); note the two spaces before a
// wrapped error.
function invalidRange(theRange, message, wrapped) {
    if (wrapped) {
        return `invalid range "${theRange}":  ${message} (${wrapped})`;
    }
    return `invalid range "${theRange}": ${message}`;
}

// frameRangeExplode (js_globals.go).
function frameRangeExplode(frameRange) {
    const frames = new Set();
    frameRange = frameRange.split("..").join("-");
    for (const part of frameRange.split(",")) {
        const startEnd = part.split("-");
        if (startEnd.length === 1) {
            const [frame, err] = parseInt64(startEnd[0]);
            if (err) throw goError(invalidRange(frameRange, part, err));
            frames.add(frame);
        } else if (startEnd.length === 2) {
            const [start, startErr] = parseInt64(startEnd[0]);
            const [end, endErr] = parseInt64(startEnd[1]);
            if (startErr || endErr) {
                throw goError(invalidRange(frameRange, part, startErr || endErr));
            }
            for (let f = start; f <= end; f++) frames.add(f);
        } else {
            throw goError(invalidRange(frameRange, part));
        }
    }
    return Array.from(frames).sort((a, b) => a - b);
}

// frameRangeMerge (js_globals.go): "3-8,13,15-17"; two frames in a row are
// written "A,B", not "A-B".
function frameRangeMerge(frames) {
    let startFrame = frames[0];
    let prevFrame = frames[0];
    const ranges = [];
    const appendRange = (from, to) => {
        if (from === to) {
            ranges.push(String(from));
        } else if (from + 1 === to) {
            ranges.push(String(from), String(to));
        } else {
            ranges.push(`${from}-${to}`);
        }
    };
    let current;
    for (current of frames) {
        if (current > prevFrame + 1) {
            appendRange(startFrame, prevFrame);
            startFrame = current;
        }
        prevFrame = current;
    }
    appendRange(startFrame, current);
    return ranges.join(",");
}

// jsFrameChunker (js_globals.go).
function frameChunker(frameRange, chunkSize) {
    frameRange = goString(frameRange).trim();
    chunkSize = goInt(chunkSize);
    if (frameRange.length === 0) throw goError(invalidRange(frameRange, "empty range"));
    if (chunkSize < 1) throw goError(`invalid chunk size, must be positive number: ${chunkSize}`);
    const frames = frameRangeExplode(frameRange);
    if (frames.length === 0) throw goError(invalidRange(frameRange, "empty range"));
    const chunks = [];
    for (let i = 0; i < frames.length; i += chunkSize) {
        chunks.push(frameRangeMerge(frames.slice(i, Math.min(i + chunkSize, frames.length))));
    }
    return chunks;
}

// jsFrameCount (js_globals.go).
function frameCount(frameRange) {
    return frameRangeExplode(goString(frameRange)).length;
}

// jsFormatTimestampLocal: Go layout "2006-01-02_150405" in local time.
function formatTimestampLocal(t) {
    const d = t instanceof Date ? t : new Date(t);
    const p = (n, w) => String(n).padStart(w, "0");
    return `${p(d.getFullYear(), 4)}-${p(d.getMonth() + 1, 2)}-${p(d.getDate(), 2)}_` +
        `${p(d.getHours(), 2)}${p(d.getMinutes(), 2)}${p(d.getSeconds(), 2)}`;
}

// jsShellSplit panics with vm.ToValue(err): the script sees the Go error
// value itself, whose string form is err.Error() (no .message).
function goErrorValue(message) {
    return Object.freeze({
        error() { return message; },
        toString() { return message; },
    });
}

// github.com/google/shlex Split at e7afc7fbc510 (the version Flamenco's
// go.mod pins): whitespace splits; "..." quotes with \ escaping any rune;
// '...' quotes literally; \ escapes outside quotes; a # that begins a word
// starts a comment to the end of the line.
function shlexSplit(s) {
    const SPACE = " \t\r\n";
    const words = [];
    const chars = Array.from(s);
    let i = 0;
    const next = () => (i < chars.length ? chars[i++] : null);
    for (;;) {
        // startState
        let c;
        do { c = next(); } while (c !== null && SPACE.includes(c));
        if (c === null) return words;
        let value = "";
        let state;
        let comment = false;
        if (c === "\"") state = "dq";
        else if (c === "'") state = "sq";
        else if (c === "\\") state = "esc";
        else if (c === "#") { state = "comment"; comment = true; }
        else { value += c; state = "word"; }
        scan: for (;;) {
            c = next();
            switch (state) {
            case "word":
                if (c === null || SPACE.includes(c)) break scan;
                if (c === "\"") state = "dq";
                else if (c === "'") state = "sq";
                else if (c === "\\") state = "esc";
                else value += c;
                break;
            case "esc":
                if (c === null) throw new Error("EOF found after escape character");
                value += c; state = "word";
                break;
            case "dqesc":
                if (c === null) throw new Error("EOF found after escape character");
                value += c; state = "dq";
                break;
            case "dq":
                if (c === null) throw new Error("EOF found when expecting closing quote");
                if (c === "\"") state = "word";
                else if (c === "\\") state = "dqesc";
                else value += c;
                break;
            case "sq":
                if (c === null) throw new Error("EOF found when expecting closing quote");
                if (c === "'") state = "word";
                else value += c;
                break;
            case "comment":
                if (c === null || c === "\n") break scan;
                break;
            }
        }
        if (!comment) words.push(value);
    }
}

function shellSplit(someCLIArgs) {
    try {
        return shlexSplit(goString(someCLIArgs));
    } catch (e) {
        throw goErrorValue(e.message);
    }
}

// Go's path.Clean.
function goClean(p) {
    if (p === "") return ".";
    const rooted = p[0] === "/";
    const out = [];
    for (const part of p.split("/")) {
        if (part === "" || part === ".") continue;
        if (part === "..") {
            if (out.length > 0 && out[out.length - 1] !== "..") out.pop();
            else if (!rooted) out.push("..");
            continue;
        }
        out.push(part);
    }
    const joined = (rooted ? "/" : "") + out.join("/");
    return joined === "" ? "." : joined;
}

// Go's path.Base, path.Ext, path.Split, path.Join.
function goBase(p) {
    if (p === "") return ".";
    while (p.length > 0 && p[p.length - 1] === "/") p = p.slice(0, -1);
    const i = p.lastIndexOf("/");
    if (i >= 0) p = p.slice(i + 1);
    return p === "" ? "/" : p;
}
function goExt(p) {
    for (let i = p.length - 1; i >= 0 && p[i] !== "/"; i--) {
        if (p[i] === ".") return p.slice(i);
    }
    return "";
}
function goSplit(p) {
    const i = p.lastIndexOf("/");
    return [p.slice(0, i + 1), p.slice(i + 1)];
}
function goJoin(elems) {
    const nonEmpty = elems.filter((e) => e !== "");
    return nonEmpty.length === 0 ? "" : goClean(nonEmpty.join("/"));
}

// pkg/crosspath, exported by js_path.go as path.basename/dirname/join/stem.
const toSlash = (p) => p.split("\\").join("/");
const crosspath = {
    basename(p) { return goBase(toSlash(goString(p))); },
    dirname(p) {
        p = goString(p);
        if (p === "") return ".";
        const [dir] = goSplit(toSlash(p));
        if (dir === "") return ".";
        return dir.length > 1 ? dir.slice(0, -1) : dir;
    },
    join(...elems) { return toSlash(goJoin(elems.map(goString))); },
    stem(p) {
        const base = crosspath.basename(p);
        return base.slice(0, base.length - goExt(base).length);
    },
};

let uuidCounter = 0;
function newUUID() {
    uuidCounter++;
    return `00000000-0000-4000-8000-${String(uuidCounter).padStart(12, "0")}`;
}

// Exports a JS value the way goja exports command parameters into a Go
// map[string]any: a copy made at call time (undefined becomes nil/null).
function exportValue(v) {
    return JSON.parse(JSON.stringify(v === undefined ? null : v, (k, x) => (x === undefined ? null : x)));
}

// A fresh runtime: the globals newGojaVM() sets, plus a log of print() and
// alert() calls.
function makeRuntime() {
    const log = [];
    const tasks = new WeakSet();
    const commands = new WeakSet();

    // author.go: AuthoredTask, with AddCommand/AddDependency exposed as
    // addCommand/addDependency (goja's UncapFieldNameMapper).
    function Task(name, taskType) {
        name = goString(name).trim();
        taskType = goString(taskType).trim();
        if (name === "") throw goError("author.Task(name, type): name is required");
        if (taskType === "") throw goError("author.Task(name, type): type is required");
        const at = {
            uuid: newUUID(),
            name: name,
            type: taskType,
            priority: 50,
            commands: [],
            dependencies: [],
            addCommand(ac) {
                if (!commands.has(ac)) throw new TypeError("addCommand() takes a command made by author.Command()");
                at.commands.push({...ac}); // appends a copy of *ac
            },
            addDependency(dep) {
                if (!tasks.has(dep)) throw new TypeError("addDependency() takes a task made by author.Task()");
                at.dependencies.push(dep); // a pointer to the task
            },
        };
        tasks.add(at);
        return at;
    }

    function Command(cmdName, parameters, totalStepCount) {
        const ac = {
            name: goString(cmdName),
            parameters: parameters === undefined || parameters === null ? null : exportValue(parameters),
            totalStepCount: goInt(totalStepCount),
        };
        commands.add(ac);
        return ac;
    }

    const globals = {
        print: (...args) => log.push({level: "print", args}),
        alert: (...args) => log.push({level: "alert", args}),
        frameChunker,
        frameCount,
        formatTimestampLocal,
        shellSplit,
        author: Object.freeze({Task, Command}),
        path: Object.freeze({...crosspath}),
        process: Object.freeze({cwd: () => "/opt/flamenco", platform: "linux"}),
    };
    return {globals, log, isTask: (t) => tasks.has(t)};
}

// An AuthoredJob as compileJob(job) sees it (author.go, job_compilers.go):
// settings and metadata copied from the submission, AddTask as addTask.
function makeJob(runtime, settings, extra) {
    const job = {
        jobID: newUUID(),
        workerTagUUID: "",
        name: "sh010 smoke",
        jobType: "vdbphoton",
        priority: 50,
        status: "under-construction",
        created: new Date(2006, 0, 2, 15, 4, 5),
        settings: {...settings},
        metadata: {"user.name": "Test Artist", project: "vdbphoton"},
        storage: {shamanCheckoutID: ""},
        tasks: [],
        addTask(at) {
            if (!runtime.isTask(at)) throw new TypeError("addTask() takes a task made by author.Task()");
            // aj.Tasks = append(aj.Tasks, *at): a copy of the task as it is now.
            job.tasks.push({...at, commands: at.commands.slice(), dependencies: at.dependencies.slice()});
        },
        ...extra,
    };
    return job;
}

// Loads the script into a fresh context (scripts are compiled in strict
// mode: goja.Compile(filename, src, true)).
function loadScript(runtime) {
    const source = fs.readFileSync(SCRIPT, "utf8");
    const context = vm.createContext({...runtime.globals});
    new vm.Script("\"use strict\";" + source, {filename: SCRIPT}).runInContext(context);
    const get = (name) => vm.runInContext(`typeof ${name} === "undefined" ? undefined : ${name}`, context);
    return {JOB_TYPE: get("JOB_TYPE"), compileJob: get("compileJob")};
}

// Compiles a job with these settings; returns {job, log} or throws what the
// script threw.
function compile(settings) {
    const runtime = makeRuntime();
    const {compileJob} = loadScript(runtime);
    assert.equal(typeof compileJob, "function", "vdbphoton.js defines no compileJob(job)");
    const job = makeJob(runtime, settings);
    compileJob(job);
    return {job, log: runtime.log};
}

// ===================================================================
// What a worker would run
// ===================================================================

// cmdParameterAsStrings (cmd_executor.go) accepts any list and formats
// non-strings with %v; a job type should only ever pass strings (an
// undefined would reach the program as "<nil>").
function stringList(params, key, where) {
    const v = params[key];
    if (v === undefined) return [];
    assert.ok(Array.isArray(v), `${where}: parameter ${key} is not a list`);
    v.forEach((x, i) => assert.equal(typeof x, "string", `${where}: ${key}[${i}] is ${JSON.stringify(x)}, not a string`));
    return v;
}

// The argv a worker executes for a command (command_exec.go cmdExecParams,
// command_blender.go cmdBlenderRenderParams / cmdBlenderRenderCommand).
function workerArgv(cmd, where) {
    const p = cmd.parameters || {};
    assert.ok(typeof p.exe === "string" && p.exe !== "", `${where}: missing 'exe' parameter`);
    switch (cmd.name) {
    case "exec":
        return [p.exe].concat(stringList(p, "args", where));
    case "blender-render": {
        const exeArgs = typeof p.exeArgs === "string" ? shlexSplit(p.exeArgs) : [];
        assert.equal(typeof p.blendfile, "string", `${where}: invalid 'blendfile' parameter`);
        // Flamenco before 3.5 required a non-empty blendfile; keep it filled.
        assert.notEqual(p.blendfile, "", `${where}: empty 'blendfile' (refused before Flamenco 3.5)`);
        return [p.exe].concat(exeArgs, stringList(p, "argsBefore", where), [p.blendfile], stringList(p, "args", where));
    }
    default:
        assert.fail(`${where}: command ${JSON.stringify(cmd.name)} is not one a worker runs here (exec, blender-render)`);
    }
}

// Checks what Flamenco itself requires of a compiled job and returns a plain
// summary: [{name, type, argv, deps: [names]}] in job order.
function summarise(job) {
    const byUUID = new Map();
    job.tasks.forEach((t, i) => {
        assert.ok(!byUUID.has(t.uuid), `task ${t.name} was added twice`);
        byUUID.set(t.uuid, i);
    });
    const names = new Set();
    return job.tasks.map((t, i) => {
        assert.ok(!names.has(t.name), `two tasks are named ${t.name}`);
        names.add(t.name);
        assert.equal(t.type, "vdbphoton", `${t.name}: task type`);
        assert.equal(t.commands.length, 1, `${t.name}: one command per task`);
        const cmd = t.commands[0];
        assert.equal(cmd.totalStepCount, 0, `${t.name}: vdbphoton reports no steps Flamenco counts, so the command must not claim any`);
        // Stored as JSON (persistence/jobs.go).
        assert.deepEqual(JSON.parse(JSON.stringify(cmd.parameters)), cmd.parameters, `${t.name}: parameters survive JSON`);
        const deps = t.dependencies.map((d) => {
            // persistence: "a task depends on a task that is not part of this job"
            assert.ok(byUUID.has(d.uuid), `${t.name} depends on a task that is not part of the job`);
            assert.ok(byUUID.get(d.uuid) < i, `${t.name} depends on ${d.name}, added after it`);
            return job.tasks[byUUID.get(d.uuid)].name;
        });
        assert.equal(new Set(deps).size, deps.length, `${t.name}: a dependency is listed twice`);
        return {name: t.name, type: t.type, argv: workerArgv(cmd, t.name), deps};
    });
}

// ===================================================================
// Checks
// ===================================================================

const checks = [];
function check(name, fn) {
    checks.push({name, fn});
}

// Expects compile(settings) to throw a single-line message starting with
// "vdbphoton:" and matching `pattern`.
function expectError(settings, pattern) {
    let thrown;
    try {
        compile(settings);
    } catch (e) {
        thrown = e;
    }
    assert.ok(thrown !== undefined, `expected an error matching ${pattern}, but the job compiled`);
    const msg = typeof thrown === "string" ? thrown : String(thrown && thrown.message);
    assert.equal(typeof thrown, "string", `expected a thrown message (string), got ${thrown}`);
    assert.match(msg, /^vdbphoton: /, `error does not say it comes from vdbphoton: ${msg}`);
    assert.ok(!msg.includes("\n"), `error is not one line: ${msg}`);
    assert.match(msg, pattern);
}

const EXE = "vdbphoton";
const SCENE = "/farm/shots/sh010/smoke.toml";
const OUT = "/farm/render/sh010/smoke_{frame:04}.exr";
const PNG = "/farm/render/sh010/smoke_{frame:04}.png";
const BASE = {scene: SCENE, output: OUT};

// The settings the Blender add-on submits: every setting, defaults where the
// artist changed nothing.
function settings(overrides) {
    return {
        vdbphoton_exe: "vdbphoton",
        chunk_size: 1,
        preview: true,
        tiles: 0,
        skip_existing: true,
        resume: true,
        extra_args: "",
        merge_args: "",
        flamenco_previews: true,
        ...BASE,
        ...overrides,
    };
}

// What `resume` (on by default) adds to every render task.
const RESUME = ["--checkpoint", "60s", "--resume"];

// A whole-frame render task, spelled out.
function chunkTask(frames, extra) {
    return {
        name: `render-${frames}`, type: "vdbphoton", deps: [],
        argv: [EXE, "render", SCENE, "--frames", frames, "-o", OUT, "--preview", PNG, "--skip-existing"].concat(RESUME, extra || []),
    };
}

// ----------------------------------------------- the stubs match Flamenco

check("stub frameChunker: Flamenco's js_globals_test.go cases", () => {
    const want = ["1-4", "5-8", "9,10,20,21", "22-25", "40"];
    assert.deepEqual(frameChunker("1..10,20..25,40,3..8", 4), want);
    assert.deepEqual(frameChunker("1-10,20-25,40", 4), want);
    assert.deepEqual(frameChunker(" 1  .. 10,\t20..25\n,40   ", 4), want);
    assert.deepEqual(frameChunker("47", 4), ["47"]);
    assert.deepEqual(frameChunker("1-3", 3), ["1-3"]);
    assert.throws(() => frameChunker("   ", 4), {name: "GoError", message: 'invalid range "": empty range'});
    assert.throws(() => frameChunker(" 1 10", 4), (e) => e.message.includes("1 10"));
    assert.deepEqual(frameRangeExplode("1..10,20..25,40"), [1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 20, 21, 22, 23, 24, 25, 40]);
    assert.throws(() => frameChunker("1-3", 0), {message: "invalid chunk size, must be positive number: 0"});
    assert.throws(() => frameChunker("10-1", 1), {message: 'invalid range "10-1": empty range'});
    assert.throws(() => frameChunker("1-3,x", 1),
        {message: 'invalid range "1-3,x":  x (strconv.ParseInt: parsing "x": invalid syntax)'});
    assert.equal(frameCount("1-3,5"), 4);
});

check("stub shellSplit: google/shlex behaviour and Flamenco's js_globals_test.go cases", () => {
    assert.deepEqual(shellSplit("--python-expr 'print(1 + 1)'"), ["--python-expr", "print(1 + 1)"]);
    assert.throws(() => shellSplit("--python-expr invalid_quoting(1 + 1)'"), (e) => String(e) === "EOF found when expecting closing quote");
    assert.deepEqual(shellSplit("  a  \"b c\" 'd \\ e' f\\ g \"h\\\"i\" x=1 #comment here"), ["a", "b c", "d \\ e", "f g", "h\"i", "x=1"]);
    assert.deepEqual(shellSplit("a#b \"\" c"), ["a#b", "", "c"]);
    assert.deepEqual(shellSplit("#only\nnext"), ["next"]);
    assert.deepEqual(shellSplit(""), []);
    assert.throws(() => shellSplit("trailing\\"), (e) => String(e) === "EOF found after escape character");
});

check("stub path module: Flamenco's crosspath_test.go cases", () => {
    const p = crosspath;
    for (const [want, input] of [[".", ""], ["justafile.txt", "justafile.txt"], ["with spaces.txt", "/Linux path/with spaces.txt"],
        ["awésom.tar.gz", "C:\\ünicode\\is\\awésom.tar.gz"],
        ["Resource with ext.ension", "\\\\?\\UNC\\ComputerName\\SharedFolder\\Resource with ext.ension"]]) {
        assert.equal(p.basename(input), want, `basename(${input})`);
    }
    for (const [want, input] of [[".", ""], [".", "justafile.txt"], ["/", "/"], ["/", "/file-at-root"], ["C:", "C:\\file-at-root"],
        ["/Linux path", "/Linux path/with spaces.txt"], ["/Mixed path/with", "/Mixed path\\with/slash.txt"],
        ["C:/ünicode/is", "C:\\ünicode\\is\\awésom.tar.gz"], ["//SERVER/ünicode/is", "\\\\SERVER\\ünicode\\is\\awésom.tar.gz"],
        ["//?/UNC/ComputerName/SharedFolder", "\\\\?\\UNC\\ComputerName\\SharedFolder\\Resource"]]) {
        assert.equal(p.dirname(input), want, `dirname(${input})`);
    }
    for (const [want, input] of [["", []], ["", [""]], ["", ["", ""]], ["a/b", ["", "", "a", "", "b", ""]],
        ["/file-at-root", ["/", "file-at-root"]], ["C:/file-at-root", ["C:", "file-at-root"]],
        ["/Linux path/with spaces.txt", ["/Linux path", "with spaces.txt"]],
        ["C:/ünicode/is/awésom.tar.gz", ["C:\\ünicode", "is\\awésom.tar.gz"]],
        ["//SERVER/mount/dir/file.txt", ["\\\\SERVER", "mount", "dir", "file.txt"]],
        ["//?/UNC/ComputerName/SharedFolder/Resource", ["\\\\?\\UNC\\ComputerName", "SharedFolder\\Resource"]]]) {
        assert.equal(p.join(...input), want, `join(${JSON.stringify(input)})`);
    }
    for (const [want, input] of [["", ""], ["stem", "stem.txt"], ["stem.tar", "stem.tar.gz"], ["file", "/path/to/file.txt"],
        ["file", "C:\\path\\to\\file.txt"], ["file", "C:\\path\\to/mixed/slashes/file.txt"],
        ["Resource with ext", "\\\\?\\UNC\\ComputerName\\SharedFolder\\Resource with ext.ension"]]) {
        assert.equal(p.stem(input), want, `stem(${input})`);
    }
});

check("stub author: Task needs a name and type; addTask copies the task", () => {
    const rt = makeRuntime();
    assert.throws(() => rt.globals.author.Task("  ", "misc"), {message: "author.Task(name, type): name is required"});
    assert.throws(() => rt.globals.author.Task("x", ""), {message: "author.Task(name, type): type is required"});
    const job = makeJob(rt, {});
    const t = rt.globals.author.Task(" t ", "misc");
    assert.equal(t.name, "t");
    job.addTask(t);
    t.addCommand(rt.globals.author.Command("echo", {message: "late"}));
    assert.equal(job.tasks[0].commands.length, 0, "a command added after addTask() is not in the job");
    assert.throws(() => t.addCommand({name: "echo", parameters: {}}), TypeError);
});

// --------------------------------------------------------- the job type

check("JOB_TYPE matches Flamenco's AvailableJobType / AvailableJobSetting schema", () => {
    const {JOB_TYPE} = loadScript(makeRuntime());
    assert.ok(JOB_TYPE && typeof JOB_TYPE === "object", "vdbphoton.js defines no JOB_TYPE");
    for (const k of Object.keys(JOB_TYPE)) {
        assert.ok(["label", "description", "settings"].includes(k), `JOB_TYPE.${k} is not in the schema`);
    }
    assert.equal(typeof JOB_TYPE.label, "string");
    assert.ok(Array.isArray(JOB_TYPE.settings) && JOB_TYPE.settings.length > 0);
    const allowed = ["key", "type", "subtype", "choices", "propargs", "description", "label", "default", "eval",
        "evalInfo", "visible", "required", "editable"];
    const keys = new Set();
    for (const s of JOB_TYPE.settings) {
        const where = `setting ${s.key}`;
        for (const k of Object.keys(s)) assert.ok(allowed.includes(k), `${where}: '${k}' is not in the schema`);
        // The key becomes a Blender RNA property name in the add-on.
        assert.match(s.key, /^[a-z_][a-z0-9_]*$/, `${where}: key`);
        assert.ok(!keys.has(s.key), `${where}: key used twice`);
        keys.add(s.key);
        assert.ok(["string", "int32", "float", "bool"].includes(s.type), `${where}: type ${s.type}`);
        if (s.subtype !== undefined) {
            assert.equal(s.type, "string", `${where}: subtype on a non-string`);
            assert.ok(["file_path", "dir_path", "file_name", "hashed_file_path"].includes(s.subtype), `${where}: subtype`);
        }
        if (s.choices !== undefined) {
            assert.equal(s.type, "string", `${where}: choices on a non-string`);
            assert.ok(s.choices.every((c) => typeof c === "string"), `${where}: choices`);
        }
        if (s.visible !== undefined) {
            assert.ok(["visible", "hidden", "submission", "web"].includes(s.visible), `${where}: visible`);
        }
        for (const b of ["required", "editable"]) {
            if (s[b] !== undefined) assert.equal(typeof s[b], "boolean", `${where}: ${b}`);
        }
        // The add-on makes a non-editable setting read-only in Blender.
        assert.notEqual(s.editable, false, `${where}: editable false would make it read-only in Blender`);
        if (s.evalInfo !== undefined) {
            assert.equal(typeof s.eval, "string", `${where}: evalInfo without eval`);
            assert.equal(typeof s.evalInfo.showLinkButton, "boolean", `${where}: evalInfo.showLinkButton`);
            assert.equal(typeof s.evalInfo.description, "string", `${where}: evalInfo.description`);
        }
        if (s.default !== undefined) {
            const ok = {
                string: (v) => typeof v === "string",
                int32: (v) => Number.isInteger(v) && v >= -2147483648 && v <= 2147483647,
                float: (v) => typeof v === "number",
                bool: (v) => typeof v === "boolean",
            }[s.type];
            assert.ok(ok(s.default), `${where}: default ${JSON.stringify(s.default)} is not a ${s.type}`);
        }
        if (s.propargs !== undefined) {
            assert.equal(typeof s.propargs, "object", `${where}: propargs`);
        }
        assert.equal(typeof s.description, "string", `${where}: no description`);
    }
    for (const k of ["vdbphoton_exe", "scene", "frames", "chunk_size", "extra_args", "tiles", "output", "skip_existing"]) {
        assert.ok(keys.has(k), `no '${k}' setting`);
    }
    const exe = JOB_TYPE.settings.find((s) => s.key === "vdbphoton_exe");
    assert.equal(exe.default, "vdbphoton");
    // The Manager exports JOB_TYPE into Go structs and hashes it as JSON for
    // its etag: nothing may be lost on the way (functions, undefined).
    const json = JSON.stringify(JOB_TYPE);
    assert.equal(JSON.stringify(JSON.parse(json)), json);
    assert.equal(JSON.parse(json).settings.length, JOB_TYPE.settings.length);
    for (const s of JOB_TYPE.settings) {
        for (const [k, v] of Object.entries(s)) {
            assert.ok(v !== undefined && typeof v !== "function", `setting ${s.key}: ${k} does not survive JSON`);
        }
    }
});

check("the script uses only what Flamenco's goja runtime gives it", () => {
    const source = fs.readFileSync(SCRIPT, "utf8");
    // No Node/browser APIs: the context has none, so a use would already
    // throw in the compile checks; these are the ones easy to miss on a
    // path not taken.
    for (const name of ["require(", "console.", "module.exports", "import ", "setTimeout", "globalThis", "process.env"]) {
        assert.ok(!source.includes(name), `vdbphoton.js uses ${name}`);
    }
    // goja (the 2023 version Flamenco pins) predates ?. and ??; keep to
    // ES2015+ features Flamenco's own scripts use.
    const code = source.replace(/\/\/.*$/gm, "").replace(/`(?:\\.|[^`\\])*`|"(?:\\.|[^"\\])*"|'(?:\\.|[^'\\])*'/g, "\"\"");
    assert.ok(!/\?\.|\?\?/.test(code), "vdbphoton.js uses ?. or ??");
});

check("frames 1-40, chunk size 10: four render tasks with the exact argv", () => {
    const {job} = compile(settings({frames: "1-40", chunk_size: 10}));
    assert.deepEqual(summarise(job), [chunkTask("1-10"), chunkTask("11-20"), chunkTask("21-30"), chunkTask("31-40")]);
});

check("frames 1-3,5,7-20, chunk size 4: non-contiguous chunks use the list syntax", () => {
    const {job} = compile(settings({frames: "1-3,5,7-20", chunk_size: 4}));
    assert.deepEqual(summarise(job),
        [chunkTask("1-3,5"), chunkTask("7-10"), chunkTask("11-14"), chunkTask("15-18"), chunkTask("19,20")]);
});

check("a single frame: one task; an output without a frame pattern is allowed", () => {
    let {job} = compile(settings({frames: "47", chunk_size: 10}));
    assert.deepEqual(summarise(job), [chunkTask("47")]);
    ({job} = compile(settings({frames: "47", output: "/farm/render/still.exr"})));
    assert.deepEqual(summarise(job)[0].argv,
        [EXE, "render", SCENE, "--frames", "47", "-o", "/farm/render/still.exr", "--preview", "/farm/render/still.png", "--skip-existing"].concat(RESUME));
});

check("frames from 1001, chunk size 4 (and Blender's 1001..1010 notation)", () => {
    const want = [chunkTask("1001-1004"), chunkTask("1005-1008"), chunkTask("1009,1010")];
    assert.deepEqual(summarise(compile(settings({frames: "1001-1010", chunk_size: 4})).job), want);
    assert.deepEqual(summarise(compile(settings({frames: "1001..1010", chunk_size: 4})).job), want);
});

check("tiles 1 is the same as no tiling", () => {
    const a = summarise(compile(settings({frames: "1-4", chunk_size: 2, tiles: 1})).job);
    const b = summarise(compile(settings({frames: "1-4", chunk_size: 2, tiles: 0})).job);
    assert.deepEqual(a, b);
    assert.deepEqual(a, [chunkTask("1,2"), chunkTask("3,4")]);
});

// The tasks of one tiled frame, spelled out.
function tiledFrame(frame, n, opts) {
    const o = {dir: "/farm/render/sh010", stem: `smoke_${String(frame).padStart(4, "0")}`, render: [], merge: [], preview: true, skip: true, resume: RESUME, ...opts};
    const tiles = [];
    const tasks = [];
    for (let i = 0; i < n; i++) {
        const tile = `${o.dir}/tiles/${o.stem}_tile${i}of${n}.exr`;
        tiles.push(tile);
        tasks.push({
            name: `render-${frame}-tile-${i}of${n}`, type: "vdbphoton", deps: [],
            argv: [EXE, "render", SCENE, "--frame", String(frame), "--tile", `${i}/${n}`, "-o", tile, "--no-preview"]
                .concat(o.skip ? ["--skip-existing"] : [], o.resume, o.render),
        });
    }
    tasks.push({
        name: `merge-${frame}`, type: "vdbphoton", deps: tasks.map((t) => t.name),
        argv: [EXE, "merge", `${o.outDir || o.dir}/${o.stem}.exr`].concat(tiles,
            o.preview ? ["--preview", `${o.outDir || o.dir}/${o.stem}.png`] : [], o.merge),
    });
    return tasks;
}

check("4 tiles, frames 1001-1002: tile tasks, then a merge per frame depending on exactly its tiles", () => {
    const {job} = compile(settings({frames: "1001-1002", tiles: 4}));
    const got = summarise(job);
    assert.deepEqual(got, tiledFrame(1001, 4).concat(tiledFrame(1002, 4)));
    // The same by identity: the merge's dependencies are the very tile tasks
    // of its frame, and nothing depends on a merge.
    for (const frame of [1001, 1002]) {
        const merge = job.tasks.find((t) => t.name === `merge-${frame}`);
        const tiles = job.tasks.filter((t) => t.name.startsWith(`render-${frame}-tile-`));
        assert.equal(tiles.length, 4);
        assert.deepEqual(merge.dependencies.map((d) => d.uuid).sort(), tiles.map((t) => t.uuid).sort());
        // The merge reads exactly the files the tile tasks write.
        const written = tiles.map((t) => { const a = workerArgv(t.commands[0], t.name); return a[a.indexOf("-o") + 1]; });
        assert.deepEqual(workerArgv(merge.commands[0], merge.name).slice(3, 7), written);
    }
    for (const t of job.tasks) {
        if (!t.name.startsWith("merge-")) assert.equal(t.dependencies.length, 0, `${t.name} has dependencies`);
    }
});

check("4 tiles of a single frame (output without a frame pattern)", () => {
    const {job} = compile(settings({frames: "1", tiles: 4, output: "/farm/render/still.exr"}));
    assert.deepEqual(summarise(job), tiledFrame(1, 4, {dir: "/farm/render", stem: "still"}));
});

check("tiles ignore chunk_size: one task per tile per frame", () => {
    const {job, log} = compile(settings({frames: "1-3", tiles: 2, chunk_size: 10}));
    assert.deepEqual(summarise(job), tiledFrame(1, 2).concat(tiledFrame(2, 2), tiledFrame(3, 2)));
    assert.ok(log.some((l) => l.args.join(" ").includes("chunk_size 10 is ignored")), "no note about chunk_size");
});

check("extra_args go to render tasks, merge_args to merge tasks, shell-split", () => {
    const extra = ["--spp", "512", "--view", "agx", "--seed", "7", "--integrator", "photon"];
    let {job} = compile(settings({frames: "1-2", chunk_size: 2, extra_args: "--spp 512  --view agx --seed \"7\" --integrator 'photon'"}));
    assert.deepEqual(summarise(job), [chunkTask("1,2", extra)]);
    ({job} = compile(settings({frames: "5", tiles: 2, extra_args: "--spp 512 --view agx --seed 7 --integrator photon",
        merge_args: "--exposure 0.5 --view agx"})));
    assert.deepEqual(summarise(job), tiledFrame(5, 2, {render: extra, merge: ["--exposure", "0.5", "--view", "agx"]}));
    // --region crops a whole-frame render; only tiling refuses it.
    ({job} = compile(settings({frames: "5", extra_args: "--region 0,0,64,64"})));
    assert.deepEqual(summarise(job), [chunkTask("5", ["--region", "0,0,64,64"])]);
});

check("skip_existing, resume and preview off", () => {
    let {job} = compile(settings({frames: "1-2", chunk_size: 2, skip_existing: false, resume: false, preview: false}));
    assert.deepEqual(summarise(job)[0].argv, [EXE, "render", SCENE, "--frames", "1,2", "-o", OUT, "--no-preview"]);
    ({job} = compile(settings({frames: "3", tiles: 2, skip_existing: false, resume: false, preview: false})));
    assert.deepEqual(summarise(job), tiledFrame(3, 2, {skip: false, resume: [], preview: false}));
});

check("resume: the artist's own --checkpoint interval is kept, --resume is the job type's", () => {
    let {job} = compile(settings({frames: "1", extra_args: "--checkpoint 5m"}));
    assert.deepEqual(summarise(job)[0].argv,
        [EXE, "render", SCENE, "--frames", "1", "-o", OUT, "--preview", PNG, "--skip-existing", "--resume", "--checkpoint", "5m"]);
    ({job} = compile(settings({frames: "2", tiles: 2, extra_args: "--checkpoint=30s"})));
    assert.deepEqual(summarise(job), tiledFrame(2, 2, {resume: ["--resume"], render: ["--checkpoint=30s"]}));
    expectError(settings({frames: "1", extra_args: "--resume"}), /--resume/);
});

check("worker commands: blender-render (previews in Flamenco) and exec run the same argv", () => {
    const a = compile(settings({frames: "1-2", chunk_size: 2, flamenco_previews: true})).job.tasks[0].commands[0];
    assert.deepEqual(a, {name: "blender-render", totalStepCount: 0, parameters: {
        exe: EXE, exeArgs: "", argsBefore: ["render"], blendfile: SCENE,
        args: ["--frames", "1,2", "-o", OUT, "--preview", PNG, "--skip-existing"].concat(RESUME)}});
    const b = compile(settings({frames: "1-2", chunk_size: 2, flamenco_previews: false})).job.tasks[0].commands[0];
    assert.deepEqual(b, {name: "exec", totalStepCount: 0, parameters: {
        exe: EXE, args: ["render", SCENE, "--frames", "1,2", "-o", OUT, "--preview", PNG, "--skip-existing"].concat(RESUME)}});
    assert.deepEqual(workerArgv(a, "a"), workerArgv(b, "b"));
    const m = compile(settings({frames: "9", tiles: 2, flamenco_previews: false})).job.tasks[2].commands[0];
    assert.deepEqual(m, {name: "exec", totalStepCount: 0, parameters: {exe: EXE, args: ["merge",
        "/farm/render/sh010/smoke_0009.exr", "/farm/render/sh010/tiles/smoke_0009_tile0of2.exr",
        "/farm/render/sh010/tiles/smoke_0009_tile1of2.exr", "--preview", "/farm/render/sh010/smoke_0009.png"]}});
});

check("an API submission with only the required settings gets the defaults", () => {
    const {job} = compile({scene: SCENE, frames: "1-2", output: OUT});
    assert.deepEqual(summarise(job), [chunkTask("1"), chunkTask("2")]);
    assert.equal(job.tasks[0].commands[0].name, "blender-render");
});

check("executable path, #### and {frame} patterns, Flamenco variables and Windows paths", () => {
    let {job} = compile(settings({frames: "7", tiles: 2, vdbphoton_exe: "{vdbphoton}", output: "{render}/sh010/smoke_####.exr"}));
    let got = summarise(job);
    assert.ok(got.every((t) => t.argv[0] === "{vdbphoton}"));
    assert.deepEqual(got.map((t) => t.argv.map((a) => a === "{vdbphoton}" ? EXE : a)),
        tiledFrame(7, 2, {dir: "{render}/sh010", stem: "smoke_0007"}).map((t) => t.argv));
    ({job} = compile(settings({frames: "12", tiles: 2, output: "S:\\render\\smoke_{frame}.exr"})));
    got = summarise(job);
    assert.deepEqual(got[0].argv.slice(7, 9), ["-o", "S:/render/tiles/smoke_12_tile0of2.exr"]);
    assert.deepEqual(got[2].argv, [EXE, "merge", "S:\\render\\smoke_12.exr", "S:/render/tiles/smoke_12_tile0of2.exr",
        "S:/render/tiles/smoke_12_tile1of2.exr", "--preview", "S:\\render\\smoke_12.png"]);
    ({job} = compile(settings({frames: "3-4", chunk_size: 2, output: "/r/{frame:6}/img.EXR"})));
    assert.deepEqual(summarise(job)[0].argv.slice(5, 9), ["-o", "/r/{frame:6}/img.EXR", "--preview", "/r/{frame:6}/img.png"]);
    ({job} = compile(settings({frames: "3", tiles: 2, output: "/r/{frame:06}/img.exr"})));
    assert.deepEqual(summarise(job)[2].argv.slice(2, 4), ["/r/000003/img.exr", "/r/000003/tiles/img_tile0of2.exr"]);
});

check("frame numbers up to vdbphoton's 9999999", () => {
    const {job} = compile(settings({frames: "9999998-9999999", chunk_size: 5}));
    assert.deepEqual(summarise(job), [chunkTask("9999998,9999999")]);
});

// ------------------------------------------------------------ bad settings

check("bad frames: empty, blank, garbage, reversed, steps, too large", () => {
    expectError(settings({frames: ""}), /"frames" is empty/);
    expectError(settings({frames: "   "}), /"frames" is empty/);
    expectError(settings({frames: "1-3,abc"}), /frames "1-3,abc" is not a frame range .*abc.*invalid syntax/);
    expectError(settings({frames: "1 10"}), /frames "1 10" is not a frame range/);
    expectError(settings({frames: "1-2-3"}), /frames "1-2-3" is not a frame range/);
    expectError(settings({frames: "10-1"}), /frames "10-1" is not a frame range .*empty range/);
    expectError(settings({frames: "1-40:2"}), /no :STEP/);
    expectError(settings({frames: "-5"}), /is not a frame range/);
    expectError(settings({frames: "12000000"}), /frame 12000000 .* out of range/);
    expectError(settings({frames: 40}), /"frames" must be a string/);
});

check("bad chunk_size and tiles", () => {
    expectError(settings({frames: "1-3", chunk_size: 0}), /chunk_size must be at least 1.* 0$/);
    expectError(settings({frames: "1-3", chunk_size: -2}), /chunk_size must be at least 1/);
    expectError(settings({frames: "1-3", chunk_size: "4"}), /"chunk_size" must be a whole number/);
    expectError(settings({frames: "1-3", tiles: -1}), /tiles must be 0 or 1 .* not -1$/);
    expectError(settings({frames: "1-3", tiles: 2.5}), /"tiles" must be a whole number/);
    expectError(settings({frames: "1-3", tiles: 5000}), /tiles must be .* not 5000$/);
});

check("bad paths and patterns", () => {
    expectError(settings({frames: "1-40", output: "/farm/render/smoke.exr"}), /no frame pattern/);
    expectError(settings({frames: "1", output: "/farm/render/smoke_{frame:04}.png"}), /must end in \.exr/);
    expectError(settings({frames: "1", output: "/farm/render/smoke_{frame:x}.exr"}), /'\{frame:x\}' .* is not a frame pattern/);
    expectError(settings({frames: "1", output: "/farm/render/smoke_{frame:0}.exr"}), /is not a frame pattern/);
    expectError(settings({frames: "1", output: "/farm/render/smoke_{frames}.exr"}), /'\{frames\}' .* is not a pattern/);
    expectError(settings({frames: "1", output: "/farm/render/smoke_{frame}_{tile}.exr"}), /must not hold \{tile\}/);
    expectError(settings({frames: "1", scene: "shots/smoke.toml"}), /scene path "shots\/smoke.toml" is relative/);
    expectError(settings({frames: "1", output: "smoke_{frame}.exr"}), /output path .* is relative/);
    expectError({frames: "1", output: OUT}, /"scene" is required/);
    expectError(settings({frames: "1", scene: ""}), /"scene" is empty/);
    expectError(settings({frames: "1", vdbphoton_exe: " "}), /"vdbphoton_exe" is empty/);
    expectError(settings({frames: "1", skip_existing: "yes"}), /"skip_existing" must be true or false/);
});

check("extra arguments that clash with the job's own or cannot be split", () => {
    expectError(settings({frames: "1", extra_args: "--frames 1-3"}), /extra_args must not contain --frames/);
    expectError(settings({frames: "1", extra_args: "--spp 4 -o /tmp/x.exr"}), /extra_args must not contain -o/);
    expectError(settings({frames: "1", extra_args: "--output=/tmp/x.exr"}), /must not contain --output/);
    expectError(settings({frames: "1", extra_args: "--no-preview"}), /must not contain --no-preview/);
    expectError(settings({frames: "1", tiles: 2, extra_args: "--region 0,0,8,8"}), /must not contain --region/);
    expectError(settings({frames: "1", extra_args: "--seed \"7"}), /extra_args .* cannot be split .*closing quote/);
    expectError(settings({frames: "1", tiles: 2, merge_args: "--preview /tmp/x.png"}), /merge_args must not contain --preview/);
});

// ===================================================================

if (require.main === module) {
    let passed = 0;
    const failed = [];
    for (const c of checks) {
        try {
            c.fn();
            passed++;
            console.log(`ok   ${c.name}`);
        } catch (e) {
            failed.push(c.name);
            console.log(`FAIL ${c.name}`);
            console.log(String(e && e.stack ? e.stack : e).split("\n").map((l) => "     " + l).join("\n"));
        }
    }
    if (failed.length > 0) {
        console.log(`${failed.length} of ${checks.length} checks failed: ${failed.join("; ")}`);
        process.exit(1);
    }
    console.log(`${passed} checks passed`);
} else {
    // For trying the stubs on other job scripts.
    module.exports = {makeRuntime, makeJob, frameChunker, shellSplit, crosspath, workerArgv};
}
