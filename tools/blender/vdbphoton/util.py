"""What the add-on's modules share: the message prefix, the one error type,
number formatting, frame lists and file-name patterns, and the one-line
form of an unexpected exception."""

import os
import re
import struct

import bpy

# The prefix of the exporter's lines on stderr (`vdbphoton_export: warning:
# ...`), which scripts and tests read: the command line's name.
PREFIX = 'vdbphoton_export'


class ExportError(Exception):
    pass


# An argument not given (where None is a value).
UNSET = object()


def f32(x):
    return struct.unpack('f', struct.pack('f', x))[0]


def rgb3(c):
    return [float(c[0]), float(c[1]), float(c[2])]


def g7(x):
    """A float32 value with the digits it has (7 significant)."""
    return float('%.7g' % float(x)) + 0.0


def rounded(v, digits=7):
    fmt = '%%.%dg' % digits
    return [float(fmt % float(x)) + 0.0 for x in v]


def matrix_rows(m, digits=9):
    fmt = '%%.%dg' % digits
    rows = [[float(fmt % float(m[i][j])) + 0.0 for j in range(4)] for i in range(4)]
    rows[3] = [0.0, 0.0, 0.0, 1.0]
    return rows


def frame_range_text(start, end, step):
    if start == end:
        return str(start)
    s = f'{start}-{end}'
    return s + (f':{step}' if step != 1 else '')


FRAMES_RE = re.compile(r'^\s*-?\d+(\s*-\s*-?\d+(\s*:\s*\d+)?)?(\s*,\s*-?\d+(\s*-\s*-?\d+(\s*:\s*\d+)?)?)*\s*$')


def expand_frames(text):
    out = []
    for part in text.split(','):
        part = part.strip()
        step = 1
        if ':' in part:
            part, s = part.split(':')
            step = max(1, int(s))
        m = re.match(r'^(-?\d+)\s*(?:-\s*(-?\d+))?$', part.strip())
        a = int(m.group(1))
        b = int(m.group(2)) if m.group(2) is not None else a
        out.extend(range(a, b + 1, step))
    return out


def compress_frames(frames):
    frames = sorted(set(frames))
    runs, i = [], 0
    while i < len(frames):
        j = i
        while j + 1 < len(frames) and frames[j + 1] == frames[j] + 1:
            j += 1
        runs.append(str(frames[i]) if i == j else f'{frames[i]}-{frames[j]}')
        i = j + 1
    return ','.join(runs)


def sequence_pattern(path):
    """Blender's BLI_path_frame_get: the last run of digits in the file name
    (before its extension). Returns (pattern with '#' * digits, number,
    digits) or None."""
    d, name = os.path.split(path)
    stem, ext = os.path.splitext(name)
    m = None
    for m in re.finditer(r'\d+', stem):
        pass
    if m is None:
        return None
    pat = stem[:m.start()] + '#' * len(m.group()) + stem[m.end():] + ext
    return os.path.join(d, pat), int(m.group()), len(m.group())


def pattern_path(pattern, frame):
    def sub(m):
        return str(frame).zfill(len(m.group()))
    d, name = os.path.split(pattern)
    return os.path.join(d, re.sub(r'#+', sub, name))


def internal_error(e):
    """An unexpected exception as one line: its type, message and where in
    this package it was raised (the innermost frame in one of its files)."""
    import traceback
    here = os.path.dirname(os.path.abspath(__file__))
    tb = [f for f in traceback.extract_tb(e.__traceback__)
          if os.path.dirname(os.path.abspath(f.filename)) == here] or \
        traceback.extract_tb(e.__traceback__)
    where = (f' ({os.path.basename(here)}/{os.path.basename(tb[-1].filename)} line '
             f'{tb[-1].lineno}, {tb[-1].name})') if tb else ''
    msg = str(e).strip().splitlines()[-1] if str(e).strip() else ''
    return (f"the export failed: {type(e).__name__}{': ' + msg if msg else ''}{where}; "
            "please report it")


def uses_nodes(idblock):
    """Blender 5 always uses nodes (use_nodes is deprecated there)."""
    if bpy.app.version >= (5, 0, 0):
        return idblock.node_tree is not None
    return bool(idblock.use_nodes)
