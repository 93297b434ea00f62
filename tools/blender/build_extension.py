"""Builds the vdbphoton Blender extension: one zip holding the add-on
(tools/blender/vdbphoton/, with its blender_manifest.toml) and the vdbphoton
binary for Linux x86-64 as bin/vdbphoton, installable with Blender 4.2+'s
Edit > Preferences > Get Extensions > Install from Disk (or
`bpy.ops.extensions.package_install_files`).

    python3 tools/blender/build_extension.py [--binary PATH] [--output ZIP]

Without --binary it runs `cargo build --release` and takes
target/release/vdbphoton ($CARGO_TARGET_DIR/release/vdbphoton when that is
set). The zip is target/vdbphoton-<version>-linux-x64.zip by default, with
every file inside one folder, vdbphoton/ (Blender's installer takes the
folder's contents; Blender 3.4-4.1 install the same zip as a legacy
add-on). The binary keeps its execute bit in the zip; Blender's installer
drops it, and the add-on gives it back on first use (binary.py).

Refused, with one line `build_extension: error: ...` and exit status 1: a
binary that is missing, not an x86-64 ELF executable, or not vdbphoton of
the version the add-on speaks to; an add-on version that differs between
blender_manifest.toml, bl_info (__init__.py) and binary.py's ADDON_VERSION.
"""

import argparse
import ast
import os
import re
import subprocess
import sys
import zipfile

HERE = os.path.dirname(os.path.abspath(__file__))
PACKAGE = os.path.join(HERE, 'vdbphoton')
REPO = os.path.dirname(os.path.dirname(HERE))
PREFIX = 'build_extension'


class BuildError(Exception):
    pass


def module_constant(path, name):
    """A literal assigned at the top level of a Python file (read, not run:
    the add-on needs Blender's bpy)."""
    with open(path, encoding='utf-8') as f:
        tree = ast.parse(f.read(), path)
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(
                isinstance(t, ast.Name) and t.id == name for t in node.targets):
            return ast.literal_eval(node.value)
    raise BuildError(f'{path}: no {name}')


def manifest_value(text, key):
    m = re.search(rf'^{key}\s*=\s*"([^"]*)"', text, re.M)
    if not m:
        raise BuildError(f'blender_manifest.toml: no {key}')
    return m.group(1)


def addon_version():
    """The add-on's version, which the manifest, bl_info and binary.py's
    ADDON_VERSION (sent to the binary) must all give."""
    with open(os.path.join(PACKAGE, 'blender_manifest.toml'), encoding='utf-8') as f:
        manifest = f.read()
    versions = {
        'blender_manifest.toml': manifest_value(manifest, 'version'),
        '__init__.py bl_info': '.'.join(
            map(str, module_constant(os.path.join(PACKAGE, '__init__.py'), 'bl_info')['version'])),
        'binary.py ADDON_VERSION': '.'.join(
            map(str, module_constant(os.path.join(PACKAGE, 'binary.py'), 'ADDON_VERSION'))),
    }
    if len(set(versions.values())) != 1:
        raise BuildError('the add-on version differs: ' +
                         ', '.join(f'{k} {v}' for k, v in versions.items()))
    if manifest_value(manifest, 'id') != 'vdbphoton':
        raise BuildError("blender_manifest.toml: the id must be 'vdbphoton' (the package's name)")
    return versions['blender_manifest.toml']


def check_binary(path):
    """An x86-64 ELF executable whose `--version` is the vdbphoton the
    add-on speaks to (binary.py's BINARY_VERSION)."""
    if not os.path.isfile(path):
        raise BuildError(f'no binary at {path}')
    with open(path, 'rb') as f:
        head = f.read(20)
    # ELF, 64-bit, little-endian; e_machine 62 = x86-64.
    if head[:4] != b'\x7fELF' or head[4] != 2 or head[5] != 1 or \
            int.from_bytes(head[18:20], 'little') != 62:
        raise BuildError(f'{path} is not an x86-64 ELF executable (the extension is linux-x64)')
    want = module_constant(os.path.join(PACKAGE, 'binary.py'), 'BINARY_VERSION')
    try:
        out = subprocess.run([path, '--version'], capture_output=True, text=True, timeout=60)
    except OSError as e:
        raise BuildError(f'cannot run {path}: {e.strerror or e}') from None
    m = re.match(r'vdbphoton (\d+)\.(\d+)\.(\d+)', out.stdout.strip())
    if out.returncode != 0 or not m:
        said = ((out.stdout or out.stderr).strip().splitlines() or [''])[0][:100]
        raise BuildError(f'{path} is not a vdbphoton binary (its --version said {said!r})')
    if (int(m.group(1)), int(m.group(2))) != tuple(want):
        raise BuildError(f'{path} is vdbphoton {m.group(0)[10:]}; the add-on speaks to '
                         f'{want[0]}.{want[1]}.x')
    return m.group(0)


def cargo_build():
    """`cargo build --release` in the repository; returns the binary's path."""
    print(f'{PREFIX}: cargo build --release', flush=True)
    try:
        r = subprocess.run(['cargo', 'build', '--release', '--bin', 'vdbphoton'], cwd=REPO)
    except OSError as e:
        raise BuildError(f'cannot run cargo: {e.strerror or e}') from None
    if r.returncode != 0:
        raise BuildError(f'cargo build --release failed (exit status {r.returncode})')
    target = os.environ.get('CARGO_TARGET_DIR') or os.path.join(REPO, 'target')
    return os.path.join(os.path.abspath(target), 'release', 'vdbphoton')


def package_files():
    """The add-on's files: the manifest and the package's Python modules
    (not caches, not a bin/ of its own)."""
    names = sorted(n for n in os.listdir(PACKAGE) if n.endswith('.py'))
    if '__init__.py' not in names:
        raise BuildError(f'{PACKAGE}: no __init__.py')
    return ['blender_manifest.toml'] + names


def write_zip(out, binary):
    """The zip, written to a temporary name and renamed when complete."""
    d = os.path.dirname(out)
    if not os.path.isdir(d):
        raise BuildError(f'cannot write {out}: folder {d} does not exist')
    tmp = os.path.join(d, f'.{os.path.basename(out)}.{os.getpid()}.tmp')

    def add(zf, arcname, path, mode):
        info = zipfile.ZipInfo.from_file(path, arcname)
        info.external_attr = (0o100000 | mode) << 16
        info.compress_type = zipfile.ZIP_DEFLATED
        with open(path, 'rb') as f:
            zf.writestr(info, f.read(), compresslevel=6)

    try:
        with zipfile.ZipFile(tmp, 'w') as zf:
            for name in package_files():
                add(zf, f'vdbphoton/{name}', os.path.join(PACKAGE, name), 0o644)
            add(zf, 'vdbphoton/bin/vdbphoton', binary, 0o755)
        os.replace(tmp, out)
    except OSError as e:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise BuildError(f'cannot write {out}: {e.strerror or e}') from None


def main(argv):
    ap = argparse.ArgumentParser(prog='build_extension.py',
                                 description='Build the vdbphoton Blender extension (a zip).')
    ap.add_argument('--binary', help='the vdbphoton binary to bundle (default: cargo build '
                    '--release, target/release/vdbphoton)')
    ap.add_argument('--output', help='the zip (default: '
                    'target/vdbphoton-<version>-linux-x64.zip)')
    a = ap.parse_args(argv)
    version = addon_version()
    binary = os.path.abspath(a.binary) if a.binary else cargo_build()
    said = check_binary(binary)
    target = os.environ.get('CARGO_TARGET_DIR') or os.path.join(REPO, 'target')
    out = os.path.abspath(a.output or os.path.join(target, f'vdbphoton-{version}-linux-x64.zip'))
    write_zip(out, binary)
    size = os.path.getsize(out)
    print(f'{PREFIX}: add-on {version}, {said} ({binary}); {size / 1e6:.1f} MB')
    print(f"Saved: '{out}'")
    return 0


if __name__ == '__main__':
    try:
        sys.exit(main(sys.argv[1:]))
    except BuildError as e:
        print(f'{PREFIX}: error: {e}', file=sys.stderr)
        sys.exit(1)
