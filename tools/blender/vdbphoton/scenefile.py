"""The scene file: vdbphoton's TOML written from the exporter's tables, and
written atomically."""

import math
import os

from .util import ExportError


def toml_str(s):
    out = ['"']
    for ch in s:
        if ch == '"':
            out.append('\\"')
        elif ch == '\\':
            out.append('\\\\')
        elif ord(ch) < 0x20 or ord(ch) == 0x7f:
            out.append('\\u%04x' % ord(ch))
        else:
            out.append(ch)
    out.append('"')
    return ''.join(out)


def toml_num(x):
    if isinstance(x, bool):
        return 'true' if x else 'false'
    if isinstance(x, int):
        return str(x)
    x = float(x)
    if not math.isfinite(x):
        raise ExportError(f'cannot write the non-finite number {x}')
    s = repr(x + 0.0)
    if '.' not in s and 'e' not in s:
        s += '.0'
    return s


def toml_value(v):
    if isinstance(v, str):
        return toml_str(v)
    if isinstance(v, (list, tuple)):
        return '[' + ', '.join(toml_value(x) for x in v) + ']'
    if isinstance(v, dict):
        return '{ ' + ', '.join(f'{k} = {toml_value(x)}' for k, x in v.items()) + ' }'
    return toml_num(v)


def to_toml(doc):
    """doc: {'header': [comment lines], 'render': {}, 'camera': {},
    'light': [{}], 'environment': {} | None, 'volume': [{'_comment': str,
    ..., 'material': {}}], 'mesh': [{'_comment': str, 'file': ..., ...}]}"""
    lines = [f'# {c}' for c in doc['header']]

    def table(name, t):
        lines.append('')
        if t.get('_comment'):
            lines.append(f"# {t['_comment']}")
        lines.append(f'[{name}]')
        for k, v in t.items():
            if not k.startswith('_'):
                lines.append(f'{k} = {toml_value(v)}')

    table('render', doc['render'])
    table('camera', doc['camera'])
    for L in doc['light']:
        lines.append('')
        if L.get('_comment'):
            lines.append(f"# {L['_comment']}")
        lines.append('[[light]]')
        for k, v in L.items():
            if not k.startswith('_'):
                lines.append(f'{k} = {toml_value(v)}')
    if doc['environment'] is not None:
        table('environment', doc['environment'])
    for v in doc['volume']:
        lines.append('')
        for c in v.get('_comment', []):
            lines.append(f'# {c}')
        lines.append('[[volume]]')
        for k, x in v.items():
            if k.startswith('_') or k == 'material':
                continue
            lines.append(f'{k} = {toml_value(x)}')
        lines.append('[volume.material]')
        for k, x in v['material'].items():
            lines.append(f'{k} = {toml_value(x)}')
    for m in doc.get('mesh', []):
        lines.append('')
        if m.get('_comment'):
            lines.append(f"# {m['_comment']}")
        lines.append('[[mesh]]')
        for k, x in m.items():
            if not k.startswith('_') and k != 'material':
                lines.append(f'{k} = {toml_value(x)}')
        if m.get('material') is not None:
            lines.append('[mesh.material]')
            for k, x in m['material'].items():
                lines.append(f'{k} = {toml_value(x)}')
    return '\n'.join(lines) + '\n'


def write_scene(path, text):
    """Atomic write (temporary name, then rename); raises ExportError."""
    path = os.path.abspath(path)
    d = os.path.dirname(path)
    if not os.path.isdir(d):
        raise ExportError(f"cannot write {path}: folder {d} does not exist")
    tmp = os.path.join(d, f'.{os.path.basename(path)}.{os.getpid()}.tmp')
    try:
        with open(tmp, 'w', encoding='utf-8') as f:
            f.write(text)
        os.replace(tmp, path)
    except OSError as e:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise ExportError(f'cannot write {path}: {e.strerror or e}') from None
