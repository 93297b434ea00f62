"""The vdbphoton binary the render engine runs: where it is found (the
add-on's preference, $VDBPHOTON, the one inside the extension, PATH) and
the check that it is a vdbphoton this add-on speaks to."""

import os
import re

import bpy

from .util import ExportError

# The add-on's own version, sent to the binary as --addon-version (which
# refuses another major version). It is also bl_info's (__init__.py) and
# blender_manifest.toml's: build_extension.py refuses to build when they differ.
ADDON_VERSION = (1, 2, 0)

# The binary's version this add-on speaks to (`vdbphoton --version`): the
# same major and minor.
BINARY_VERSION = (0, 2)

# Debian 12's package of the OpenVDB library the binary links to (it pulls
# in TBB, Imath, Blosc and Boost's iostreams, the binary's other libraries).
OPENVDB_PACKAGE = 'libopenvdb10.0'


def addon_version_text():
    return '.'.join(map(str, ADDON_VERSION))


def bundled_binary():
    """Where the extension holds its binary: bin/vdbphoton beside the add-on's
    files (tools/blender/build_extension.py puts it there). A checkout's
    tools/blender/vdbphoton/ has none."""
    return os.path.join(os.path.dirname(os.path.abspath(__file__)), 'bin', 'vdbphoton')


def preference_binary():
    """The add-on's preference "vdbphoton binary" (an absolute path), or ''."""
    addon = bpy.context.preferences.addons.get(__package__)
    if addon is not None and getattr(addon.preferences, 'binary', ''):
        return bpy.path.abspath(addon.preferences.binary)
    return ''


def make_executable(path):
    """Blender's extension installer extracts files without their Unix
    modes (Python's zipfile), so the bundled binary arrives without its
    execute bit: give it back (to whoever may read it)."""
    if os.access(path, os.X_OK):
        return
    mode = os.stat(path).st_mode
    try:
        os.chmod(path, mode | ((mode & 0o444) >> 2))
    except OSError as e:
        raise ExportError(f"the vdbphoton binary inside the extension, '{path}', is not "
                          f"executable and cannot be made so: {e.strerror or e}") from None


def find_binary():
    """The vdbphoton binary: the add-on's preference, else $VDBPHOTON, else
    the one inside the extension (bin/vdbphoton), else `vdbphoton` on PATH.
    An explicit choice (the preference, the variable) goes before the
    bundled binary, so that another build can be tried with the extension
    installed."""
    import shutil
    exe = preference_binary() or os.environ.get('VDBPHOTON', '')
    bundled = bundled_binary()
    if not exe and os.path.isfile(bundled):
        make_executable(bundled)
        exe = bundled
    exe = exe or (shutil.which('vdbphoton') or '')
    if not exe:
        raise ExportError(f"the vdbphoton binary was not found: not at {bundled}, where the "
                          "vdbphoton extension holds it, nor on PATH (or set its path in the "
                          "add-on's preferences: Edit > Preferences > Add-ons > vdbphoton)")
    if not (os.path.isfile(exe) and os.access(exe, os.X_OK)):
        raise ExportError(f"the vdbphoton binary '{exe}' is not an executable file")
    return exe


def check_binary(exe):
    """Checks that `exe` is a vdbphoton of the version this add-on speaks to
    (`vdbphoton --version`); returns its version text."""
    import subprocess
    try:
        out = subprocess.run([exe, '--version'], capture_output=True, text=True, timeout=20)
    except (OSError, subprocess.SubprocessError) as e:
        raise ExportError(f"cannot run the vdbphoton binary '{exe}': {e}") from None
    m = re.match(r'vdbphoton (\d+)\.(\d+)\.(\d+)', out.stdout.strip())
    if out.returncode != 0 or not m:
        # The dynamic loader's complaint when a shared library is missing.
        lib = re.search(r'error while loading shared libraries: ([^:\s]+)', out.stderr or '')
        if lib:
            raise ExportError(f"the vdbphoton binary '{exe}' cannot start: {lib.group(1)} is "
                              "missing (it needs OpenVDB 10's shared libraries; Debian 12: "
                              f"apt-get install {OPENVDB_PACKAGE})")
        said = ((out.stdout or out.stderr).strip().splitlines() or [''])[0][:80]
        raise ExportError(f"'{exe}' is not a vdbphoton binary (its --version said {said!r})")
    if (int(m.group(1)), int(m.group(2))) != BINARY_VERSION:
        raise ExportError(f"'{exe}' is vdbphoton {m.group(0)[10:]}; this add-on "
                          f"({addon_version_text()}) needs vdbphoton "
                          f"{BINARY_VERSION[0]}.{BINARY_VERSION[1]}.x")
    return m.group(0)
