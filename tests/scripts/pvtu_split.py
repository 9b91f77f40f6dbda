#!/usr/bin/env python3
"""Splits a .vtu tetrahedral mesh written by i2m (raw or zlib-compressed) into pieces and a
.pvtu naming them, as `mpirun i2m -o OUT.pvtu --vtu-raw` writes them: every piece a VTK XML
UnstructuredGrid with appended raw data (UInt64 headers), Points Float64, point data
GlobalNodeId Int64 (here the vertex's index in the input + an offset), connectivity / offsets
Int64, types UInt8, cell data "material" (the input's type).  Tets go to pieces by the rank of
their centroid along the longest axis of the mesh's bounding box, so the pieces share the
vertices on the seams between them.  Test fixture for i2m-check (tests/scripts/test_check_pvtu.sh); the standard library only.

  pvtu_split.py IN.vtu OUT.pvtu [--pieces N] [--offset K] [--break KIND]

KIND makes a broken distributed mesh (each must make i2m-check fail):
  coords    a seam vertex one ulp away in piece 1 (one global id, two points)
  shared    a seam vertex of piece 1 under a new global id (two ids at one point)
  noids     piece 1 without GlobalNodeId
  onesided  a tet of piece 1 on a face it shares with piece 0 split in three at a new point of
            that face: piece 0 sees the face, piece 1 sees three others
  missing   the .pvtu names one more piece, which does not exist
Prints one line: what was broken (global ids, piece), for the test's messages."""
import argparse
import os
import re
import struct
import sys
import zlib
from array import array

TYPES = {'Float64': 'd', 'Float32': 'f', 'Int64': 'q', 'UInt64': 'Q', 'Int32': 'i',
         'UInt32': 'I', 'Int16': 'h', 'UInt16': 'H', 'Int8': 'b', 'UInt8': 'B'}


def attr(tag, name):
    m = re.search(r'\b%s="([^"]*)"' % name, tag)
    return m.group(1) if m else None


def inflate(data, start, hsize):
    """A zlib-compressed appended array at start: header [blocks, block size, last partial
    block size, compressed sizes], then the blocks."""
    def num(k):
        return int.from_bytes(data[start + k * hsize:start + (k + 1) * hsize], 'little')
    nblocks, out, pos = num(0), b'', start + (3 + num(0)) * hsize
    for b in range(nblocks):
        size = num(3 + b)
        out += zlib.decompress(data[pos:pos + size])
        pos += size
    return out


def read_vtu(path):
    """The arrays of an i2m .vtu (appended raw or zlib-compressed, little endian) by name."""
    data = open(path, 'rb').read()
    head, sep, _ = data.partition(b'<AppendedData')
    if not sep or sys.byteorder != 'little':
        sys.exit('%s: not an appended VTU (or a big-endian host)' % path)
    app = data.index(b'_', len(head)) + 1
    xml = head.decode()
    vtkfile = xml[:xml.index('>', xml.index('<VTKFile'))]
    hsize = 8 if attr(vtkfile, 'header_type') == 'UInt64' else 4
    compressed = attr(vtkfile, 'compressor') == 'vtkZLibDataCompressor'
    arrays = {}
    for tag in re.findall(r'<DataArray[^>]*>', xml):
        ty, name, off = attr(tag, 'type'), attr(tag, 'Name'), int(attr(tag, 'offset'))
        start = app + off
        a = array(TYPES[ty])
        if compressed:
            a.frombytes(inflate(data, start, hsize))
        else:
            nbytes = int.from_bytes(data[start:start + hsize], 'little')
            a.frombytes(data[start + hsize:start + hsize + nbytes])
        arrays[name] = (ty, a)
    return arrays


def write_vtu(path, xyz, gid, tets, mat_type, mat):
    """One piece: xyz flat [3n] doubles, gid [n] or None, tets flat [4m] local ids, mat [m]."""
    nv, nt = len(xyz) // 3, len(tets) // 4
    blocks = [('Float64', 'Points', array('d', xyz)),
              ('Int64', 'connectivity', array('q', tets)),
              ('Int64', 'offsets', array('q', range(4, 4 * nt + 1, 4))),
              ('UInt8', 'types', array('B', [10]) * nt),
              (mat_type, 'material', array(TYPES[mat_type], mat))]
    if gid is not None:
        blocks.append(('Int64', 'GlobalNodeId', array('q', gid)))
    offs, acc = {}, 0
    for ty, name, a in blocks:
        offs[name] = acc
        acc += 8 + len(a) * a.itemsize

    def da(ty, name, extra=''):
        return ('        <DataArray type="%s" Name="%s"%s format="appended" offset="%d"/>\n'
                % (ty, name, extra, offs[name]))
    xml = ('<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid" version="1.0" '
           'byte_order="LittleEndian" header_type="UInt64">\n  <UnstructuredGrid>\n'
           '    <Piece NumberOfPoints="%d" NumberOfCells="%d">\n      <Points>\n%s      </Points>\n'
           % (nv, nt, da('Float64', 'Points', ' NumberOfComponents="3"')))
    if gid is not None:
        xml += ('      <PointData GlobalIds="GlobalNodeId">\n%s      </PointData>\n'
                % da('Int64', 'GlobalNodeId'))
    xml += ('      <Cells>\n%s%s%s      </Cells>\n      <CellData Scalars="material">\n%s'
            '      </CellData>\n    </Piece>\n  </UnstructuredGrid>\n'
            '  <AppendedData encoding="raw">\n   _'
            % (da('Int64', 'connectivity'), da('Int64', 'offsets'), da('UInt8', 'types'),
               da(mat_type, 'material')))
    with open(path, 'wb') as f:
        f.write(xml.encode())
        for _, _, a in blocks:
            f.write(struct.pack('<Q', len(a) * a.itemsize))
            f.write(a.tobytes())
        f.write(b'\n  </AppendedData>\n</VTKFile>\n')


def write_pvtu(path, sources, mat_type):
    with open(path, 'w') as f:
        f.write('<?xml version="1.0"?>\n<VTKFile type="PUnstructuredGrid" version="1.0" '
                'byte_order="LittleEndian" header_type="UInt64">\n'
                '  <PUnstructuredGrid GhostLevel="0">\n'
                '    <PPointData GlobalIds="GlobalNodeId">\n'
                '      <PDataArray type="Int64" Name="GlobalNodeId"/>\n    </PPointData>\n'
                '    <PCellData Scalars="material">\n'
                '      <PDataArray type="%s" Name="material"/>\n    </PCellData>\n'
                '    <PPoints>\n      <PDataArray type="Float64" Name="Points" '
                'NumberOfComponents="3"/>\n    </PPoints>\n' % mat_type)
        for s in sources:
            f.write('    <Piece Source="%s"/>\n' % s)
        f.write('  </PUnstructuredGrid>\n</VTKFile>\n')


def split(xyz, conn, npieces):
    """Piece of every tet: rank of its centroid along the longest axis, in equal shares."""
    nv, nt = len(xyz) // 3, len(conn) // 4
    ext = [max(xyz[a::3]) - min(xyz[a::3]) for a in range(3)]
    ax = ext.index(max(ext))
    key = [sum(xyz[3 * conn[4 * t + j] + ax] for j in range(4)) for t in range(nt)]
    order = sorted(range(nt), key=key.__getitem__)
    piece = [0] * nt
    for r, t in enumerate(order):
        piece[t] = r * npieces // nt
    return piece


class Piece:
    def __init__(self):
        self.verts = []  # input vertex of each local vertex
        self.local = {}  # input vertex -> local
        self.tets = []   # flat local ids
        self.mat = []

    def vertex(self, v):
        if v not in self.local:
            self.local[v] = len(self.verts)
            self.verts.append(v)
        return self.local[v]


def make_pieces(xyz, conn, mat, npieces):
    piece = split(xyz, conn, npieces)
    pieces = [Piece() for _ in range(npieces)]
    for t in range(len(conn) // 4):
        p = pieces[piece[t]]
        p.tets.extend(p.vertex(conn[4 * t + j]) for j in range(4))
        p.mat.append(mat[t])
    return pieces


def seam_vertex(pieces):
    """An input vertex in pieces 0 and 1."""
    for v in pieces[1].verts:
        if v in pieces[0].local:
            return v
    sys.exit('pieces 0 and 1 share no vertex')


def next_ulp(x):
    b = struct.unpack('<q', struct.pack('<d', x))[0]
    return struct.unpack('<d', struct.pack('<q', b + (1 if x >= 0 else -1)))[0]


def split_shared_face(pieces, xyz, new_vertex):
    """Splits a tet of piece 1 on a face of piece 0 at a new point of that face (xyz grows)."""
    p0, p1 = pieces[0], pieces[1]
    faces0 = set()
    for t in range(len(p0.tets) // 4):
        vs = [p0.verts[i] for i in p0.tets[4 * t:4 * t + 4]]
        for f in range(4):
            faces0.add(tuple(sorted(vs[:f] + vs[f + 1:])))
    for t in range(len(p1.tets) // 4):
        loc = p1.tets[4 * t:4 * t + 4]
        for f in range(4):
            face = [loc[j] for j in range(4) if j != f]
            if tuple(sorted(p1.verts[i] for i in face)) not in faces0:
                continue
            # a point inside the face, off its centroid (the probe there must be inside a tet)
            w = (0.5, 0.3, 0.2)
            pt = [sum(w[k] * xyz[3 * p1.verts[face[k]] + a] for k in range(3)) for a in range(3)]
            xyz.extend(pt)
            m = p1.vertex(new_vertex)
            # replacing one corner of the face by a point of it keeps the orientation
            new = []
            for j in range(4):
                if j != f:
                    new.extend(m if i == j else loc[i] for i in range(4))
            p1.tets[4 * t:4 * t + 4] = new[0:4]
            p1.tets.extend(new[4:12])
            p1.mat.extend([p1.mat[t]] * 2)
            return [p1.verts[i] for i in face]
    sys.exit('piece 1 shares no face with piece 0')


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('vtu')
    ap.add_argument('pvtu')
    ap.add_argument('--pieces', type=int, default=3)
    ap.add_argument('--offset', type=int, default=1000)
    ap.add_argument('--break', dest='kind', default='none',
                    choices=['none', 'coords', 'shared', 'noids', 'onesided', 'missing'])
    a = ap.parse_args()
    arr = read_vtu(a.vtu)
    xyz = list(arr['Points'][1])
    mat_type, mat = arr['material']
    pieces = make_pieces(xyz, arr['connectivity'][1], mat, a.pieces)
    nv = len(xyz) // 3
    gid = {v: v + a.offset for v in range(nv)}
    coords = {}  # (piece, input vertex) -> other coordinates
    ids = {}     # (piece, input vertex) -> other global id
    what = ''
    if a.kind == 'coords':
        v = seam_vertex(pieces)
        coords[(1, v)] = [next_ulp(xyz[3 * v])] + xyz[3 * v + 1:3 * v + 3]
        what = 'global id %d moved in piece 1' % gid[v]
    elif a.kind == 'shared':
        v = seam_vertex(pieces)
        ids[(1, v)] = nv + a.offset + 1000
        what = 'global ids %d and %d at one point' % (gid[v], ids[(1, v)])
    elif a.kind == 'onesided':
        gid[nv] = nv + a.offset
        face = split_shared_face(pieces, xyz, nv)
        what = 'face of global ids %s split in piece 1' % ' '.join(str(gid[v]) for v in face)
    base = os.path.splitext(a.pvtu)[0]
    sources = []
    for p, pc in enumerate(pieces):
        name = base + '_%d.vtu' % p
        sources.append(os.path.basename(name))
        pxyz = []
        for v in pc.verts:
            pxyz.extend(coords.get((p, v), xyz[3 * v:3 * v + 3]))
        pgid = [ids.get((p, v), gid[v]) for v in pc.verts]
        if a.kind == 'noids' and p == 1:
            pgid = None
        write_vtu(name, pxyz, pgid, pc.tets, mat_type, pc.mat)
    if a.kind == 'missing':
        sources.append(os.path.basename(base) + '_%d.vtu' % a.pieces)
        what = 'piece %s is missing' % sources[-1]
    write_pvtu(a.pvtu, sources, mat_type)
    print(what or '%d pieces' % a.pieces)


if __name__ == '__main__':
    main()
