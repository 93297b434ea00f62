# Writes the two AFL++ render findings of stop 28 as small files (the
# originals were mutated copies of 34 KB and 245 KB files):
#   afl_temperature_far.vdb: a density and a temperature grid on the same
#     voxels, the temperature's transform scaled by -600 in y and z, so its
#     voxels lie 10^5 density voxels away (121 s and 3 GB for a 16 x 12
#     render before the majorant grid's cells could grow);
#   afl_density_1e115.vdb: a density grid translated by -1.8e115 in z
#     (beyond single precision; rendered black without a word, and the
#     emission grid's box overflowed the majorant's cell count).
# Run with Debian's python3-openvdb: /usr/bin/python3 make_afl_cases.py DIR
import struct
import sys
import pyopenvdb as vdb

out = sys.argv[1] if len(sys.argv) > 1 else "."

def cube(name, value, n=16):
    g = vdb.FloatGrid()
    g.name = name
    g.gridClass = vdb.GridClass.FOG_VOLUME
    g.fill((0, 0, 0), (n - 1, n - 1, n - 1), value, active=True)
    return g

s = 0.0625
d = cube("density", 0.5)
d.transform = vdb.createLinearTransform(voxelSize=s)
t = cube("temperature", 1.5)
t.transform = vdb.createLinearTransform(
    [[s, 0, 0, 0], [0, -600 * s * 16, 0, 0], [0, 0, -600 * s * 16, 0], [0, 0, 0, 1]])
vdb.write(f"{out}/afl_temperature_far.vdb", [d, t])

# OpenVDB will not make such a transform (its Python constructor refuses
# a translation past about 1e29): write -1000 and change that double's
# bytes, as the fuzzer did.
d = cube("density", 0.5, 8)
d.transform = vdb.createLinearTransform(
    [[s, 0, 0, 0], [0, s, 0, 0], [0, 0, s, 0], [-0.25, -0.25, -1000.0, 1]])
t = cube("temperature", 1.5, 8)
t.transform = vdb.createLinearTransform(voxelSize=s)
path = f"{out}/afl_density_1e115.vdb"
vdb.write(path, [d, t])
data = open(path, "rb").read()
old, new = struct.pack("<d", -1000.0), struct.pack("<d", -1.8e115)
assert data.count(old) == 1, data.count(old)
open(path, "wb").write(data.replace(old, new))
