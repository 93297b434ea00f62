#!/usr/bin/python3
"""Minimise a failing .vdb input found by `vdbfuzz run`.

    tools/fuzz/minimize.py INPUT SEED OUT --program PATH/vdbphoton [--failure crash|hang]

Keeps the failure (a signal under glibc's heap checks, or a run over 2 s)
while reverting the bytes in which INPUT differs from SEED (the seed file it
was mutated from, same length: field and byte mutations), in halving chunks,
then cutting whole trailing grids' worth of bytes where the file still
fails. Needs only Python 3; runs `PROGRAM info FILE` as the campaign does.
"""
import argparse
import os
import subprocess
import tempfile

MALLOC_DEBUG = "/usr/lib/x86_64-linux-gnu/libc_malloc_debug.so.0"


def fails(program, data, failure, scratch):
    path = os.path.join(scratch, "try.vdb")
    with open(path, "wb") as f:
        f.write(data)
    env = dict(os.environ, RUST_BACKTRACE="0")
    if os.path.exists(MALLOC_DEBUG):
        env.update(LD_PRELOAD=MALLOC_DEBUG, MALLOC_CHECK_="3")
    try:
        r = subprocess.run([program, "info", path], env=env, capture_output=True, timeout=6)
    except subprocess.TimeoutExpired:
        return failure == "hang"
    if failure == "crash":
        return r.returncode < 0 or r.returncode not in (0, 1)
    return False


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("input")
    ap.add_argument("seed")
    ap.add_argument("out")
    ap.add_argument("--program", required=True)
    ap.add_argument("--failure", default="crash", choices=["crash", "hang"])
    ap.add_argument("--tries", type=int, default=3, help="runs that must all fail (heap damage is not always caught)")
    a = ap.parse_args()
    data = bytearray(open(a.input, "rb").read())
    seed = open(a.seed, "rb").read()
    with tempfile.TemporaryDirectory() as scratch:
        def still(d):
            return all(fails(a.program, bytes(d), a.failure, scratch) for _ in range(a.tries))

        assert still(data), "the input does not fail"
        if len(data) == len(seed):
            diff = [i for i in range(len(data)) if data[i] != seed[i]]
            chunk = max(1, len(diff) // 2)
            while chunk >= 1 and diff:
                i = 0
                while i < len(diff):
                    part = diff[i:i + chunk]
                    trial = bytearray(data)
                    for j in part:
                        trial[j] = seed[j]
                    if still(trial):
                        data = trial
                        diff = diff[:i] + diff[i + chunk:]
                    else:
                        i += chunk
                chunk //= 2
            print(f"{len(diff)} bytes differ from the seed: {diff[:16]}")
        # Cut the tail where the failure does not need it.
        cut = len(data) // 2
        while cut >= 16:
            if still(data[:-cut]):
                data = data[:-cut]
            else:
                cut //= 2
    open(a.out, "wb").write(data)
    print(f"{a.out}: {len(data)} bytes")


if __name__ == "__main__":
    main()
