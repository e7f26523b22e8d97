#!/usr/bin/env python3
"""Hand-made hostile inputs (the attack of issue 17, redone): bit flips, truncation, header
fields set to 0 / huge / negative, NaN/inf in text numbers, long lines, deep nesting, made from the
seed corpora in fuzz/corpus/. Written to tests/data/fuzz/TARGET/mut_*; inputs found by the fuzzers
are added beside them as crash_*/timeout_*/oom_* (never regenerated). Deterministic (seed 17):
    python3 tests/data/fuzz/make_inputs.py
"""
import glob, gzip, os, random, struct

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(HERE)))
CORPUS = os.path.join(ROOT, "fuzz", "corpus")
rng = random.Random(17)


def put(target, name, data):
    d = os.path.join(HERE, target)
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, "mut_" + name), "wb") as f:
        f.write(data if isinstance(data, bytes) else data.encode("latin-1"))


def seed(target, name):
    with open(os.path.join(CORPUS, target, name), "rb") as f:
        return f.read()


def patch(b, off, fmt, value):
    b = bytearray(b)
    struct.pack_into(fmt, b, off, value)
    return bytes(b)


def flips(target, data, count, keep_head=0):
    for i in range(count):
        b = bytearray(data)
        for _ in range(rng.randint(1, 8)):
            p = rng.randrange(keep_head, len(b))
            b[p] ^= 1 << rng.randrange(8)
        put(target, "flip%02d" % i, bytes(b))


def cuts(target, data, count):
    for i in range(count):
        put(target, "cut%02d" % i, data[: rng.randrange(1, len(data))])


def main():
    for old in glob.glob(os.path.join(HERE, "*", "mut_*")):
        os.remove(old)
    nii = seed("nifti", "tiny_int16.nii")
    lab = seed("nifti", "tiny_uint8_labels.nii")
    fields = {"dim0_0": (40, "<h", 0), "dim0_8": (40, "<h", 8), "dim1_0": (42, "<h", 0), "dim2_neg": (44, "<h", -3),
              "dim3_huge": (46, "<h", 32767), "datatype_999": (70, "<h", 999), "datatype_rgb": (70, "<h", 128),
              "bitpix_0": (72, "<h", 0), "bitpix_neg": (72, "<h", -16), "voxoff_0": (108, "<f", 0.0),
              "voxoff_huge": (108, "<f", 3e38), "voxoff_nan": (108, "<f", float("nan")), "voxoff_neg": (108, "<f", -352.0),
              "pixdim3_1e30": (88, "<f", 1e30), "pixdim1_0": (80, "<f", 0.0), "pixdim2_inf": (84, "<f", float("inf")),
              "slope_nan": (112, "<f", float("nan")), "inter_inf": (116, "<f", float("inf")),
              "srow_inf": (280, "<f", float("inf")), "srow_far": (324, "<f", -2147483649.0),
              "quatern_3": (256, "<f", 3.0), "qoffset_nan": (268, "<f", float("nan")), "qform_neg": (252, "<h", -1),
              "sizeof_0": (0, "<i", 0), "sizeof_swapped_540": (0, ">i", 540)}
    for name, (off, fmt, v) in fields.items():
        put("nifti", name + ".nii", patch(nii, off, fmt, v))
        put("nifti", name + ".nii.gz", gzip.compress(patch(nii, off, fmt, v), mtime=0))
    put("nifti", "ext_size_huge.nii", patch(lab, 352, "<i", 1 << 30))
    put("nifti", "ext_size_neg.nii", patch(lab, 352, "<i", -16))
    put("nifti", "ext_size_8.nii", patch(lab, 352, "<i", 8))
    xml_at = lab.find(b"<CIFTI")
    head, tail = lab[:xml_at], lab[xml_at:]
    long_table = b"<LabelTable><Label Key=\"1\"><![CDATA[" + b"x" * 70000
    pad = (-(len(long_table) + 8)) % 16
    ext = struct.pack("<ii", len(long_table) + pad + 8, 30) + long_table + b"\0" * pad
    body = lab[struct.unpack_from("<f", lab, 108)[0].__int__():]
    longx = bytearray(lab[:348] + b"\1\0\0\0" + ext + body)
    struct.pack_into("<f", longx, 108, float(352 + len(ext)))
    put("nifti", "label_table_70k.nii", bytes(longx))
    nested = b"<LabelTable>" + b"<Label Key=\"1\">" * 5000
    pad = (-(len(nested) + 8)) % 16
    ext = struct.pack("<ii", len(nested) + pad + 8, 30) + nested + b"\0" * pad
    deep = bytearray(lab[:348] + b"\1\0\0\0" + ext + body)
    struct.pack_into("<f", deep, 108, float(352 + len(ext)))
    put("nifti", "label_table_nested.nii", bytes(deep))
    put("nifti", "label_key_text.nii", lab.replace(b'Key="52"', b'Key="5x"'))
    put("nifti", "label_raw_bytes.nii", lab.replace(b"aorta", b"\x01\xff\x1b[2J"))
    flips("nifti", nii, 20)
    flips("nifti", lab, 10)
    cuts("nifti", nii, 8)
    gz = seed("nifti", "tiny_float.nii.gz")
    flips("nifti", gz, 10, keep_head=10)
    put("nifti", "gz_cut.nii.gz", gz[: len(gz) - 12])
    # NRRD
    nrrd = seed("nrrd", "raw.nrrd").decode("latin-1")
    subs = {"dir_nan": ("(0.8,0,0)", "(nan,0,0)"), "dir_inf": ("(0,0,2.5)", "(0,0,inf)"), "dir_1e30": ("(0,0,2.5)", "(0,0,1e30)"),
            "origin_inf": ("(-40,30,700)", "(-40,inf,700)"), "origin_far": ("(-40,30,700)", "(-40,30,-2147483649)"),
            "sizes_0": ("sizes: 6 5 4", "sizes: 6 0 4"), "sizes_neg": ("sizes: 6 5 4", "sizes: 6 -5 4"),
            "sizes_huge": ("sizes: 6 5 4", "sizes: 60000 50000 40000"), "sizes_text": ("sizes: 6 5 4", "sizes: 6 5abc 4"),
            "sizes_two": ("sizes: 6 5 4", "sizes: 6 5"), "type_bad": ("type: short", "type: quaternion"),
            "encoding_bad": ("encoding: raw", "encoding: bzip2"), "datafile": ("encoding: raw", "encoding: raw\ndata file: /etc/passwd"),
            "datafile_list": ("encoding: raw", "encoding: raw\ndata file: LIST"),
            "longline": ("# SoftAtlas fuzz seed", "# " + "y" * 70000)}
    for name, (a, b) in subs.items():
        put("nrrd", name + ".nrrd", nrrd.replace(a, b))
    put("nrrd", "no_blank.nrrd", nrrd.replace("\n\n", "\n"))
    cuts("nrrd", nrrd.encode("latin-1"), 10)
    flips("nrrd", seed("nrrd", "gzip.nrrd"), 10)
    # MetaImage
    mha = seed("metaimage", "raw.mha").decode("latin-1")
    subs = {"ndims_0": ("NDims = 3", "NDims = 0"), "ndims_huge": ("NDims = 3", "NDims = 2147483647"),
            "dimsize_0": ("DimSize = 6 5 4", "DimSize = 6 0 4"), "dimsize_neg": ("DimSize = 6 5 4", "DimSize = -6 5 4"),
            "dimsize_huge": ("DimSize = 6 5 4", "DimSize = 65536 65536 65536"), "dimsize_short": ("DimSize = 6 5 4", "DimSize = 6"),
            "spacing_nan": ("ElementSpacing = 0.8 0.8 2.5", "ElementSpacing = 0.8 nan 2.5"),
            "spacing_1e30": ("ElementSpacing = 0.8 0.8 2.5", "ElementSpacing = 0.8 0.8 1e30"),
            "offset_inf": ("Offset = -40 30 700", "Offset = -40 inf 700"), "matrix_nan": ("TransformMatrix = 1 0 0", "TransformMatrix = nan 0 0"),
            "type_bad": ("MET_SHORT", "MET_STRING"), "channels": ("ElementType", "ElementNumberOfChannels = 100000\nElementType"),
            "datafile_missing": ("ElementDataFile = LOCAL", "ElementDataFile = nothere.raw"),
            "datafile_pattern": ("ElementDataFile = LOCAL", "ElementDataFile = slice%03d.raw 1 10 1"),
            "headersize": ("ElementType", "HeaderSize = -1\nElementType"), "compressed_lie": ("CompressedData = False", "CompressedData = True"),
            "longline": ("ObjectType = Image", "ObjectType = Image\nComment = " + "z" * 70000)}
    for name, (a, b) in subs.items():
        put("metaimage", name + ".mha", mha.replace(a, b))
    raw = mha.encode("latin-1")
    data_at = raw.find(b"LOCAL\n") + 6
    for i, cut in enumerate(sorted(rng.sample(range(1, len(raw)), 12)) + [data_at, len(raw) - 1]):
        put("metaimage", "trunc%02d.mha" % i, raw[:cut])
    flips("metaimage", seed("metaimage", "zlib.mha"), 10)
    # DICOM
    dcm = seed("dicom", "minimal.dcm")
    flips("dicom", dcm, 20, keep_head=132)
    cuts("dicom", dcm, 10)
    for tag, name in ((b"\x28\x00\x10\x00US\x02\x00", "rows"), (b"\x28\x00\x11\x00US\x02\x00", "cols"),
                      (b"\x28\x00\x00\x01US\x02\x00", "bits_alloc"), (b"\x28\x00\x01\x01US\x02\x00", "bits_stored"),
                      (b"\x28\x00\x02\x01US\x02\x00", "high_bit"), (b"\x28\x00\x02\x00US\x02\x00", "samples")):
        at = dcm.find(tag) + len(tag)
        for v in (0, 1, 0xFFFF, 33):
            put("dicom", "%s_%d.dcm" % (name, v), dcm[:at] + struct.pack("<H", v) + dcm[at + 2:])
    at = dcm.find(b"\xe0\x7f\x10\x00OW\x00\x00") + 8
    put("dicom", "pixel_len_huge.dcm", dcm[:at] + struct.pack("<I", 0xFFFFFFF0) + dcm[at + 4:])
    put("dicom", "pixel_len_odd.dcm", dcm[:at] + struct.pack("<I", 23) + dcm[at + 4:])
    put("dicom", "ipp_nan.dcm", dcm.replace(b"-40\\30\\700", b"nan\\30\\70 "))
    put("dicom", "spacing_0.dcm", dcm.replace(b"0.8\\0.8", b"0.0\\0.0"))
    # Meshes
    obj = seed("mesh_obj", "liver_1000.obj").decode()
    lines = obj.splitlines()
    vline = next(i for i, l in enumerate(lines) if l.startswith("v "))
    for name, text in {"far_z": "v 0 0 -2147483649", "nan": "v nan 0 0", "inf": "v 0 inf 0", "huge": "v 1e300 0 0",
                       "words": "v one two three"}.items():
        l2 = list(lines)
        l2[vline] = text
        put("mesh_obj", name + ".obj", "\n".join(l2) + "\n")
    fline = next(i for i, l in enumerate(lines) if l.startswith("f "))
    for name, text in {"idx_huge": "f 1 2 99999999999999999999", "idx_zero": "f 0 1 2", "idx_text": "f 1 2x 3",
                       "idx_slashes": "f 1/2/3/4 2 3", "idx_vt": "f 1/99 2/99 3/99", "polygon": "f 1 2 3 4 5 6 7 8 9"}.items():
        l2 = list(lines)
        l2[fline] = text
        put("mesh_obj", name + ".obj", "\n".join(l2) + "\n")
    put("mesh_obj", "longline.obj", "# " + "c" * 70000 + "\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    flips("mesh_obj", obj.encode(), 4)
    ply = seed("mesh_ply", "kidney_right.ply")
    hdr_end = ply.find(b"end_header\n")
    h = ply[:hdr_end].decode()
    import re
    for name, rep in {"vcount_huge": (r"element vertex \d+", "element vertex 4000000000"),
                      "fcount_huge": (r"element face \d+", "element face 2000000000"),
                      "vcount_neg": (r"element vertex \d+", "element vertex -5"),
                      "fcount_text": (r"element face \d+", "element face 12abc"),
                      "no_props": (r"element face \d+", "element junk 999999999999\nelement face 10")}.items():
        put("mesh_ply", name + ".ply", re.sub(rep[0], rep[1], h, count=1).encode() + ply[hdr_end:])
    flips("mesh_ply", ply[:hdr_end + 11 + 6000], 4, keep_head=hdr_end + 11)
    cuts("mesh_ply", ply, 2)
    asc = seed("mesh_ply", "tetra_ascii.ply").decode()
    put("mesh_ply", "list_huge.ply", asc.replace("3 0 2 1", "200 0 2 1"))
    put("mesh_ply", "list_zero.ply", asc.replace("3 0 2 1", "0 0 2 1"))
    put("mesh_ply", "coord_nan.ply", asc.replace("1 0 0 2", "nan 0 0 2"))
    put("mesh_ply", "idx_neg.ply", asc.replace("3 0 2 1", "3 0 -2 1"))
    stl = seed("mesh_stl", "liver_binary.stl")
    put("mesh_stl", "count_huge.stl", stl[:80] + struct.pack("<I", 0xFFFFFFFF) + stl[84:])
    put("mesh_stl", "count_zero.stl", stl[:80] + struct.pack("<I", 0) + stl[84:])
    nan_stl = bytearray(stl)
    struct.pack_into("<f", nan_stl, 84 + 12, float("nan"))
    put("mesh_stl", "coord_nan.stl", bytes(nan_stl))
    far_stl = bytearray(stl)
    struct.pack_into("<f", far_stl, 84 + 12, -2147483649.0)
    put("mesh_stl", "coord_far.stl", bytes(far_stl))
    cuts("mesh_stl", stl, 6)
    astl = seed("mesh_stl", "liver_ascii.stl").decode()
    put("mesh_stl", "ascii_nan.stl", astl.replace("vertex ", "vertex nan ", 1))
    put("mesh_stl", "ascii_cut.stl", astl[: len(astl) // 2])
    flips("mesh_stl", astl.encode(), 6)
    off = seed("mesh_off", "liver_200.off").decode()
    offl = off.splitlines()
    for name, text in {"counts_huge": "4000000000 2000000000 0", "counts_neg": "-1 -1 0", "counts_text": "12abc 3 0"}.items():
        l2 = list(offl)
        l2[2] = text
        put("mesh_off", name + ".off", "\n".join(l2) + "\n")
    put("mesh_off", "face_idx.off", off.replace("\n3 ", "\n3 999999 ", 1))
    put("mesh_off", "face_k_huge.off", off.replace("\n3 ", "\n2000000000 ", 1))
    put("mesh_off", "coord_nan.off", "\n".join(offl[:3] + ["nan 0 0"] + offl[4:]) + "\n")
    cuts("mesh_off", off.encode(), 6)
    flips("mesh_off", off.encode(), 6)
    # Organ sets
    od = seed("organ_set", "demo.txt").decode()
    first_row = od.split("--- connections.csv\n")[1].splitlines()[1]
    parts = first_row.split(",")
    def row(i, v):
        p = list(parts)
        p[i] = v
        return ",".join(p)
    for name, text in {"vertex_1e999": row(1, "1e999"), "vertex_12abc": row(1, "12abc"), "vertex_huge": row(3, "99999999999"),
                       "length_nan": row(4, "nan"), "length_inf": row(4, "inf"), "stiffness_neg": row(5, "-5"),
                       "fields_7": first_row + ",1", "raw_bytes": row(0, "\x01\xff\x1b[2J")}.items():
        put("organ_set", name + ".txt", od.replace(first_row, text))
    put("organ_set", "cr_only.txt", od.split("--- connections.csv\n")[0] + "\n--- connections.csv\n" +
        od.split("--- connections.csv\n")[1].replace("\n", "\r"))
    put("organ_set", "version_2.txt", od.replace("softatlas_organ_set: 1", "softatlas_organ_set: 2"))
    put("organ_set", "version_text.txt", od.replace("softatlas_organ_set: 1", "softatlas_organ_set: one"))
    put("organ_set", "no_version.txt", od.replace("softatlas_organ_set: 1", ""))
    put("organ_set", "deep_flow.txt", "softatlas_organ_set: 1\norgans: " + "[" * 20000 + "\n")
    put("organ_set", "deep_block.txt", "softatlas_organ_set: 1\norgans:\n" + "".join(" " * i + "- \n" for i in range(600)))
    put("organ_set", "young_nan.txt", od.replace("young_modulus_pa: 4000", "young_modulus_pa: .nan", 1))
    put("organ_set", "label_huge.txt", od.replace("label: 5", "label: 99999999999999999999", 1))
    put("organ_set", "fixed_1e999.txt", od.replace("fixed_vertices: [", "fixed_vertices: [1e999, ", 1))
    put("organ_set", "longline.txt", od.replace("# SoftAtlas", "# " + "q" * 70000, 1))
    flips("organ_set", od.encode(), 10)
    # Lessons, device scripts, seeds, build.yaml: long lines, deep nesting, NaN/inf, huge numbers.
    for target, name in (("lesson", "liver_mobility.yaml"), ("device_script", "liver_mobility.pass.yaml"),
                         ("seeds", "heart_aorta.yaml"), ("build_yaml", "build.yaml")):
        text = seed(target, name).decode()
        put(target, "longline.yaml", text + "# " + "w" * 70000 + "\n")
        put(target, "long_value.yaml", text.replace(": ", ": \"" + "v" * 70000 + "\" #", 1))
        put(target, "deep_flow.yaml", "a: " + "[" * 20000 + "\n")
        put(target, "deep_map.yaml", "a: " + "{b: " * 5000 + "\n")
        put(target, "anchors.yaml", "a: &a [x, x, x, x, x, x, x, x, x]\nb: &b [*a, *a, *a, *a, *a, *a, *a, *a, *a]\n"
            "c: &c [*b, *b, *b, *b, *b, *b, *b, *b, *b]\nd: &d [*c, *c, *c, *c, *c, *c, *c, *c, *c]\n" + text)
        for i, (a, b) in enumerate(((r"\b\d+(\.\d+)?\b", "nan"), (r"\b\d+(\.\d+)?\b", "1e999"), (r"\b\d+(\.\d+)?\b", "-1e308"),
                                     (r"\b\d+(\.\d+)?\b", "12abc"), (r"\b\d+(\.\d+)?\b", "99999999999999999999"))):
            put(target, "num%d.yaml" % i, re.sub(a, b, text))
        flips(target, text.encode(), 10)
        cuts(target, text.encode(), 5)
    ds = seed("device_script", "liver_mobility.pass.yaml").decode()
    put("device_script", "timeline_long.yaml", ds.replace("- {t_s: 0.6, offset_mm: [0, 0, -12]}",
        "\n        ".join("- {t_s: %d, offset_mm: [0, 0, -12]}" % (i + 1) for i in range(3000))))
    put("device_script", "click_nan.yaml", ds.replace("click_mm: [33, 131, 1129]", "click_mm: [.nan, .inf, -.inf]"))
    les = seed("lesson", "liver_mobility.yaml").decode()
    put("lesson", "say_100k.yaml", les.replace("We look at the upper abdomen", "W" * 70000, 1))
    put("lesson", "wait_600.yaml", les.replace("wait: {seconds: 0.2}", "wait: {seconds: 600}"))
    put("lesson", "organ_set_missing.yaml", les.replace("organ_set: ../atlas", "organ_set: ../nothere"))
    put("lesson", "organ_set_abs.yaml", les.replace("organ_set: ../atlas", "organ_set: /proc/self"))


if __name__ == "__main__":
    main()
