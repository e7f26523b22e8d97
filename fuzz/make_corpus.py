#!/usr/bin/env python3
"""Writes the seed corpora fuzz/corpus/TARGET/ from the project's own small files (data/,
../shared/data): valid inputs that reach deep into each reader. Re-run after a format changes:
    python3 fuzz/make_corpus.py
"""
import gzip, os, shutil, struct, sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SHARED = os.path.join(os.path.dirname(ROOT), "shared", "data")
OUT = os.path.join(ROOT, "fuzz", "corpus")


def put(target, name, data):
    d = os.path.join(OUT, target)
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, name), "wb") as f:
        f.write(data if isinstance(data, bytes) else data.encode())


def read(path):
    with open(path, "rb") as f:
        return f.read()


def small_nifti(nx=6, ny=5, nz=4, datatype=4, bitpix=16, ext=b""):
    h = bytearray(348)
    struct.pack_into("<i", h, 0, 348)
    struct.pack_into("<8h", h, 40, 3, nx, ny, nz, 1, 1, 1, 1)
    struct.pack_into("<hh", h, 70, datatype, bitpix)
    struct.pack_into("<8f", h, 76, 1, 0.8, 0.8, 2.5, 1, 1, 1, 1)
    vox = 352 + len(ext)
    struct.pack_into("<fff", h, 108, vox, 1.0, -1024.0)
    h[123] = 2
    struct.pack_into("<hh", h, 252, 1, 1)
    struct.pack_into("<6f", h, 256, 0, 0, 1, -40, 30, 700)
    struct.pack_into("<12f", h, 280, -0.8, 0, 0, 40, 0, -0.8, 0, 30, 0, 0, 2.5, 700)
    h[344:348] = b"n+1\0"
    n = nx * ny * nz
    body = bytes((i * 7) % 256 for i in range(n * bitpix // 8))
    return bytes(h) + (b"\1\0\0\0" if ext else b"\0\0\0\0") + ext + body


def label_table_ext():
    xml = ('<CIFTI Version="2"><Matrix><MatrixIndicesMap AppliesToMatrixDimension="0" '
           'IndicesMapToDataType="CIFTI_INDEX_TYPE_LABELS"><NamedMap><MapName>labels</MapName>'
           '<LabelTable><Label Key="0" Red="0" Green="0" Blue="0" Alpha="0"><![CDATA[unknown]]></Label>'
           '<Label Key="5" Red="1" Green="0" Blue="0" Alpha="1"><![CDATA[liver]]></Label>'
           '<Label Key="52" Red="1" Green="0" Blue="0" Alpha="1">aorta</Label></LabelTable>'
           '</NamedMap></MatrixIndicesMap></Matrix></CIFTI>').encode()
    pad = (-(len(xml) + 8)) % 16
    content = xml + b"\0" * pad
    return struct.pack("<ii", len(content) + 8, 30) + content


def minimal_dicom():
    """A 4 x 3 CT slice, explicit VR little endian, with the tags the reader needs."""
    def el(group, elem, vr, value):
        if isinstance(value, str):
            value = value.encode()
            if len(value) % 2:
                value += b"\0" if vr == "UI" else b" "
        if vr in ("OB", "OW", "SQ", "UN", "UT"):
            return struct.pack("<HH2sHI", group, elem, vr.encode(), 0, len(value)) + value
        return struct.pack("<HH2sH", group, elem, vr.encode(), len(value)) + value
    meta_body = el(0x0002, 0x0001, "OB", b"\0\1") + el(0x0002, 0x0002, "UI", "1.2.840.10008.5.1.4.1.1.2") + \
        el(0x0002, 0x0003, "UI", "1.2.3.4.5.6.7") + el(0x0002, 0x0010, "UI", "1.2.840.10008.1.2.1")
    meta = el(0x0002, 0x0000, "UL", struct.pack("<I", len(meta_body))) + meta_body
    pixels = struct.pack("<12h", *range(-6, 6))
    ds = el(0x0008, 0x0016, "UI", "1.2.840.10008.5.1.4.1.1.2") + el(0x0008, 0x0018, "UI", "1.2.3.4.5.6.7") + \
        el(0x0008, 0x0060, "CS", "CT") + el(0x0020, 0x0032, "DS", "-40\\30\\700") + \
        el(0x0020, 0x0037, "DS", "1\\0\\0\\0\\1\\0") + el(0x0028, 0x0002, "US", struct.pack("<H", 1)) + \
        el(0x0028, 0x0004, "CS", "MONOCHROME2") + el(0x0028, 0x0010, "US", struct.pack("<H", 3)) + \
        el(0x0028, 0x0011, "US", struct.pack("<H", 4)) + el(0x0028, 0x0030, "DS", "0.8\\0.8") + \
        el(0x0028, 0x0100, "US", struct.pack("<H", 16)) + el(0x0028, 0x0101, "US", struct.pack("<H", 16)) + \
        el(0x0028, 0x0102, "US", struct.pack("<H", 15)) + el(0x0028, 0x0103, "US", struct.pack("<H", 1)) + \
        el(0x0028, 0x1052, "DS", "0") + el(0x0028, 0x1053, "DS", "1") + el(0x7FE0, 0x0010, "OW", pixels)
    return b"\0" * 128 + b"DICM" + meta + ds


def main():
    shutil.rmtree(OUT, ignore_errors=True)
    # NIfTI: the shipped small label maps (gzip), and tiny headers plain and gzip, with a label table.
    for name in ("pulmonary_artery.nii.gz", "heart_on_ct_heart_crop_grid.nii.gz"):
        put("nifti", name, read(os.path.join(ROOT, "data", "sample", name)))
    put("nifti", "tiny_int16.nii", small_nifti())
    put("nifti", "tiny_uint8_labels.nii", small_nifti(datatype=2, bitpix=8, ext=label_table_ext()))
    put("nifti", "tiny_float.nii.gz", gzip.compress(small_nifti(datatype=16, bitpix=32), 6, mtime=0))
    # NRRD and MetaImage: 6 x 5 x 4 shorts, raw and gzip, LPS geometry.
    nx, ny, nz = 6, 5, 4
    body = struct.pack("<%dh" % (nx * ny * nz), *[(i * 37) % 2000 - 1000 for i in range(nx * ny * nz)])
    hdr = ("NRRD0004\n# SoftAtlas fuzz seed\ntype: short\ndimension: 3\nspace: left-posterior-superior\n"
           "sizes: %d %d %d\nspace directions: (0.8,0,0) (0,0.8,0) (0,0,2.5)\nkinds: domain domain domain\n"
           "endian: little\nencoding: %s\nspace origin: (-40,30,700)\n\n")
    put("nrrd", "raw.nrrd", (hdr % (nx, ny, nz, "raw")).encode() + body)
    put("nrrd", "gzip.nrrd", (hdr % (nx, ny, nz, "gzip")).encode() + gzip.compress(body, 6, mtime=0))
    mha = ("ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\n"
           "CompressedData = %s\nTransformMatrix = 1 0 0 0 1 0 0 0 1\nOffset = -40 30 700\n"
           "CenterOfRotation = 0 0 0\nAnatomicalOrientation = RAI\nElementSpacing = 0.8 0.8 2.5\n"
           "DimSize = %d %d %d\nElementType = MET_SHORT\nElementDataFile = LOCAL\n")
    put("metaimage", "raw.mha", (mha % ("False", nx, ny, nz)).encode() + body)
    import zlib
    packed = zlib.compress(body, 6)
    put("metaimage", "zlib.mha", (mha % ("True", nx, ny, nz)).replace("ElementType", "CompressedDataSize = %d\nElementType" % len(packed)).encode() + packed)
    # DICOM: only a minimal explicit-little-endian file made by hand (the real slices of
    # ../shared/data's abdomen slab are 150 KB each and not used: nothing adds them at run time).
    put("dicom", "minimal.dcm", minimal_dicom())
    # Meshes: the 1000-face liver as OBJ, and the same surface as ASCII/binary STL and OFF; PLY of the demo set.
    obj = read(os.path.join(ROOT, "data", "meshes", "liver_1000.obj")).decode()
    put("mesh_obj", "liver_1000.obj", obj)
    put("mesh_obj", "tetra_slashes.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nvt 0 0\nvn 0 0 1\n"
        "f 1/1/1 3/1/1 2/1/1\nf 1//1 2//1 4//1\nf 2 3 4\nf -4 -1 -2\n")
    V, F = [], []
    for line in obj.splitlines():
        t = line.split()
        if t and t[0] == "v":
            V.append(tuple(float(x) for x in t[1:4]))
        elif t and t[0] == "f":
            F.append(tuple(int(x.split("/")[0]) - 1 for x in t[1:4]))
    Fs = F[:200]
    ascii_stl = "solid liver\n" + "".join(
        "facet normal 0 0 0\n outer loop\n" + "".join("  vertex %g %g %g\n" % V[i] for i in f) + " endloop\nendfacet\n" for f in Fs
    ) + "endsolid liver\n"
    put("mesh_stl", "liver_ascii.stl", ascii_stl)
    binary = bytearray(b"binary stl fuzz seed".ljust(80, b" ")) + struct.pack("<I", len(Fs))
    for f in Fs:
        binary += struct.pack("<3f", 0, 0, 0) + b"".join(struct.pack("<3f", *V[i]) for i in f) + b"\0\0"
    put("mesh_stl", "liver_binary.stl", bytes(binary))
    used = sorted({i for f in Fs for i in f})
    remap = {v: k for k, v in enumerate(used)}
    off = "OFF\n# fuzz seed\n%d %d 0\n" % (len(used), len(Fs)) + "".join("%g %g %g\n" % V[i] for i in used) + \
        "".join("3 %d %d %d\n" % tuple(remap[i] for i in f) for f in Fs)
    put("mesh_off", "liver_200.off", off)
    put("mesh_ply", "kidney_right.ply", read(os.path.join(ROOT, "data", "atlas", "organs", "kidney_right.ply")))
    ply_ascii = "ply\nformat ascii 1.0\ncomment fuzz seed\nelement vertex 4\nproperty float x\nproperty float y\n" \
        "property float z\nproperty uchar red\nelement face 4\nproperty list uchar int vertex_indices\nend_header\n" \
        "0 0 0 1\n1 0 0 2\n0 1 0 3\n0 0 1 4\n3 0 2 1\n3 0 1 3\n3 1 2 3\n3 0 3 2\n"
    put("mesh_ply", "tetra_ascii.ply", ply_ascii)
    # Organ set: atlas.yaml + the first rows of connections.csv (the entry splits at the marker).
    atlas = read(os.path.join(ROOT, "data", "atlas", "atlas.yaml")).decode()
    csv = read(os.path.join(ROOT, "data", "atlas", "connections.csv")).decode().splitlines()
    put("organ_set", "demo.txt", atlas + "\n--- connections.csv\n" + "\n".join(csv[:40]) + "\n")
    # Lessons and device scripts as shipped; seeds and build.yaml as the docs show them.
    for name in sorted(os.listdir(os.path.join(ROOT, "data", "lessons"))):
        if name.endswith(".yaml"):
            put("lesson", name, read(os.path.join(ROOT, "data", "lessons", name)))
    for name in sorted(os.listdir(os.path.join(ROOT, "data", "lessons", "scripts"))):
        put("device_script", name, read(os.path.join(ROOT, "data", "lessons", "scripts", name)))
    put("seeds", "heart_aorta.yaml", "organs:\n  heart: [[10.5, -20, 30], [12, -18, 31]]\n  aorta: [[0, 5, 40]]\n"
        "background: [[-50, 0, 0], [60.25, 1e1, 2]]\n")
    put("build_yaml", "build.yaml", "organs: [pulmonary_artery, heart]\nbudget: {pulmonary_artery: 700}\n"
        "smoothing_iterations: 20\nsmoothing_passband: 0.1\nspeck_share: 0.01\nremesh_iterations: 3\n"
        "connect_distance_mm: 3\nconnect_spacing_mm: 6\nconnect_stiffness: 5\nanchor_count: 12\n")
    # More seeds and build.yaml files: the docs' example, the demo set's organs (data/atlas/atlas.yaml)
    # and the first names of the TotalSegmentator table (../shared/data/ct, when present), every
    # build.yaml key (docs/pipeline.md), block and flow style, comments, CRLF.
    atlas_names = [l.split("name:")[1].strip() for l in atlas.splitlines() if l.strip().startswith("- name:")]
    tsv = os.path.join(SHARED, "ct", "totalsegmentator_label_table.tsv")
    table = [l.split("\t")[1] for l in read(tsv).decode().splitlines()[1:9]] if os.path.exists(tsv) else ["spleen", "liver"]
    put("seeds", "docs_liver_spleen.yaml", "organs:\n  liver: [[-80.5, 12.0, -790.0], [-60.0, 30.5, -785.0]]\n"
        "  spleen: [[95.0, 40.0, -780.0]]\nbackground: [[0.0, 80.0, -790.0]]\n")
    put("seeds", "atlas_organs_block.yaml", "# one seed per organ of the demo set\norgans:\n" + "".join(
        "  %s:\n    - [%g, %g, %g]\n    - [%g, %g, %g]\n" % (n, -60 + 12 * i, 10.5 - i, -790 + 3 * i, -58 + 12 * i, 12, -788 + 3 * i)
        for i, n in enumerate(atlas_names)) + "background:\n  - [0, 80, -790]\n")
    put("seeds", "table_organs_crlf.yaml", ("organs:\r\n" + "".join("  %s: [[%d, %d.25, -7%02d.5]]\r\n" % (n, 10 * i, -i, i)
        for i, n in enumerate(table)) + "background: [[-1e2, 0, 0]]\r\n"))
    put("build_yaml", "all_keys.yaml", "# every key of docs/pipeline.md\norgans: [%s]\nbudget:\n  %s: 5000\n  %s: 800\n"
        "smoothing_iterations: 15\nsmoothing_passband: 0.05\nspeck_share: 0.02\nremesh_iterations: 5\n"
        "wrap_alpha_mm: 0\nconnect_distance_mm: 4\nconnect_spacing_mm: 6\nconnect_stiffness: 50\n"
        "connect_pairs:\n  - [%s, %s]\n  - [%s, %s]\nanchor_count: 6\nanchor_spacing_mm: 15\n"
        % (", ".join(atlas_names[:6]), atlas_names[1], atlas_names[4], atlas_names[1], atlas_names[2],
           atlas_names[4], atlas_names[5]))
    put("build_yaml", "groups_flow.yaml", "{organs: [organs, bones, %s], budget: {%s: 1000}, anchor_count: 0, "
        "wrap_alpha_mm: 1.5}\n" % (table[0], table[1]))


if __name__ == "__main__":
    sys.exit(main())
