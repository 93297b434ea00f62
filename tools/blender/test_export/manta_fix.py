"""Make Mantaflow read caches inside the pip `bpy` module (Blender 5.0.1).

In the bpy wheel every Python type of Mantaflow's `manta` module has
`object` as its only base (`manta.LevelsetGrid.__mro__` is (LevelsetGrid,
object)), so Blender's fluid scripts fail at once ("'LevelsetGrid' object
has no attribute 'setConst'") and a domain never reads its cache. fix()
gives those types their C++ bases back by writing `tp_base`, `tp_bases` and
`tp_mro` of the (static) type objects, CPython 3.11's layout on 64-bit
platforms, then PyType_Modified(). The C++ classes use single inheritance,
so a derived object is also a valid base object.

Used by tests only (tools/blender/test_export/render_blend.py), so that
Cycles renders a real smoke domain; fix() returns False (and changes
nothing) where the layout is not the expected one.
"""
import ctypes
import sys

PARENTS = {
    'GridBase': 'PbClass', 'Grid_Real': 'GridBase', 'Grid_Vec3': 'GridBase',
    'Grid_int': 'GridBase', 'LevelsetGrid': 'Grid_Real', 'MACGrid': 'Grid_Vec3',
    'FlagGrid': 'Grid_int',
    'Grid4dBase': 'PbClass', 'Grid4d_Real': 'Grid4dBase', 'Grid4d_Vec3': 'Grid4dBase',
    'Grid4d_Vec4': 'Grid4dBase', 'Grid4d_int': 'Grid4dBase',
    'Shape': 'PbClass', 'Box': 'Shape', 'Sphere': 'Shape', 'Cylinder': 'Shape',
    'Slope': 'Shape', 'NullShape': 'Shape',
    'ParticleBase': 'PbClass',
    'ParticleSystem_BasicParticleData': 'ParticleBase',
    'ParticleSystem_ParticleIndexData': 'ParticleBase',
    'ParticleSystem_TurbulenceParticleData': 'ParticleBase',
    'ParticleSystem_VortexParticleData': 'ParticleBase',
    'BasicParticleSystem': 'ParticleSystem_BasicParticleData',
    'ParticleIndexSystem': 'ParticleSystem_ParticleIndexData',
    'TurbulenceParticleSystem': 'ParticleSystem_TurbulenceParticleData',
    'VortexParticleSystem': 'ParticleSystem_VortexParticleData',
    'ParticleDataBase': 'PbClass', 'ParticleDataImpl_Real': 'ParticleDataBase',
    'ParticleDataImpl_Vec3': 'ParticleDataBase', 'ParticleDataImpl_int': 'ParticleDataBase',
    'Mesh': 'PbClass', 'VortexSheetMesh': 'Mesh', 'MeshDataBase': 'PbClass',
    'MeshDataImpl_Real': 'MeshDataBase', 'MeshDataImpl_Vec3': 'MeshDataBase',
    'MeshDataImpl_int': 'MeshDataBase',
    'Solver': 'PbClass', 'MovingObstacle': 'PbClass', 'NoiseField': 'PbClass',
    'Timings': 'PbClass',
}
# PyTypeObject offsets (CPython 3.11, 64-bit).
OFF_BASE, OFF_BASES, OFF_MRO = 256, 336, 344
_keep = []


def _ptr(addr):
    return ctypes.c_void_p.from_address(addr)


def fix():
    if sys.version_info[:2] != (3, 11) or ctypes.sizeof(ctypes.c_void_p) != 8:
        return False
    try:
        import manta
    except ImportError:
        return False
    types = {}
    for n in dir(manta):
        c = getattr(manta, n)
        if isinstance(c, type):
            types[c.__name__] = c
    if 'LevelsetGrid' not in types or 'Grid_Real' not in types:
        return False
    if hasattr(types['LevelsetGrid'], 'setConst'):
        return True  # inheritance intact: nothing to do
    if _ptr(id(object) + OFF_MRO).value != id(object.__mro__):
        return False
    for name, c in types.items():
        if _ptr(id(c) + OFF_MRO).value != id(c.__mro__):
            return False
    done = set()

    def do(name):
        if name in done:
            return
        done.add(name)
        par = PARENTS.get(name)
        if par is None or par not in types or name not in types:
            return
        do(par)
        t, b = types[name], types[par]
        bases, mro = (b,), (t,) + b.__mro__
        _keep.extend([bases, mro])
        _ptr(id(t) + OFF_BASE).value = id(b)
        _ptr(id(t) + OFF_BASES).value = id(bases)
        _ptr(id(t) + OFF_MRO).value = id(mro)
        ctypes.pythonapi.PyType_Modified(ctypes.py_object(t))

    for n in list(types):
        do(n)
    return hasattr(types['LevelsetGrid'], 'setConst')
