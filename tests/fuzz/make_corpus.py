#!/usr/bin/env python3
"""Writes the fuzz harnesses' seed corpora (tests/fuzz/corpus/<harness>/): small files of every
variant the readers accept (PLY ascii / little / big endian with faces and extra properties,
PCD ascii / binary / binary_compressed organized or not, 16-bit PNG and both camera JSON forms,
STL / OBJ / OFF, ASCII point files), written here from scratch so that no third-party data enters the repository.
scripts/fuzz.sh adds the heads of ../shared/data's real files at run time. The database seed
comes from `binpose train` (pass the binary as the first argument)."""
import os
import struct
import subprocess
import sys
import zlib

HERE = os.path.dirname(os.path.abspath(__file__))
TETRA = [(0.0, 0.0, 0.0), (10.0, 0.0, 0.0), (0.0, 10.0, 0.0), (0.0, 0.0, 10.0)]
FACES = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]


def write(harness, name, data):
    folder = os.path.join(HERE, "corpus", harness)
    os.makedirs(folder, exist_ok=True)
    with open(os.path.join(folder, name), "wb") as f:
        f.write(data if isinstance(data, bytes) else data.encode())


def ply_files():
    head = "ply\nformat {}\ncomment seed\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
    ascii_text = head.format("ascii 1.0") + "property float nx\nproperty float ny\nproperty float nz\n"
    ascii_text += "element face 4\nproperty list uchar int vertex_indices\nend_header\n"
    ascii_text += "".join(f"{x} {y} {z} 0 0 1\n" for x, y, z in TETRA)
    ascii_text += "".join(f"3 {a} {b} {c}\n" for a, b, c in FACES)
    write("ply", "tetra_ascii", ascii_text)
    body = b"".join(struct.pack("<3f", *p) for p in TETRA)
    write("ply", "cloud_le", (head.format("binary_little_endian 1.0") + "end_header\n").encode() + body)
    big = ("ply\nformat binary_big_endian 1.0\nelement vertex 4\nproperty double x\nproperty double y\n"
           "property double z\nproperty uchar confidence\nelement face 4\n"
           "property list int uint vertex_indices\nproperty float quality\nend_header\n").encode()
    big += b"".join(struct.pack(">3dB", *p, 7) for p in TETRA)
    big += b"".join(struct.pack(">i3If", 3, *f, 0.5) for f in FACES)
    write("ply", "tetra_be_double", big)


def lzf_literal(raw):
    """LZF stream of literal runs only (control byte n-1 then n <= 32 bytes), valid for liblzf."""
    return b"".join(bytes([len(raw[i:i + 32]) - 1]) + raw[i:i + 32] for i in range(0, len(raw), 32))


def pcd_files():
    def header(fields, size, kind, count, width, height, data):
        return (f"# .PCD v0.7\nVERSION 0.7\nFIELDS {fields}\nSIZE {size}\nTYPE {kind}\nCOUNT {count}\n"
                f"WIDTH {width}\nHEIGHT {height}\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {width * height}\nDATA {data}\n")
    text = header("x y z normal_x normal_y normal_z", "4 4 4 4 4 4", "F F F F F F", "1 1 1 1 1 1", 2, 2, "ascii")
    text += "".join(f"{x} {y} {z} 0 0 1\n" for x, y, z in TETRA[:3]) + "nan nan nan 0 0 1\n"
    write("pcd", "organized_ascii", text)
    body = b"".join(struct.pack("<3fI", *p, 0xFF00FF) for p in TETRA)
    write("pcd", "binary_rgb", header("x y z rgb", "4 4 4 4", "F F F U", "1 1 1 1", 4, 1, "binary").encode() + body)
    columns = b"".join(struct.pack("<4f", *(p[k] for p in TETRA)) for k in range(3))
    packed = lzf_literal(columns)
    compressed = header("x y z", "4 4 4", "F F F", "1 1 1", 4, 1, "binary_compressed").encode()
    write("pcd", "compressed", compressed + struct.pack("<II", len(packed), len(columns)) + packed)


def png16(width, height, values):
    def chunk(kind, payload):
        return struct.pack(">I", len(payload)) + kind + payload + struct.pack(">I", zlib.crc32(kind + payload))
    rows = b"".join(b"\0" + b"".join(struct.pack(">H", v) for v in values[r * width:(r + 1) * width])
                    for r in range(height))
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 16, 0, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b""))


def tiff(width, height, samples, fmt, sample_format, values, compression=1, payload=None):
    """Little-endian TIFF of one strip: `samples` values a pixel packed by struct `fmt` (SampleFormat
    1 unsigned, 2 signed, 3 float); `payload` replaces the packed strip (a compressed one)."""
    strip = payload if payload is not None else b"".join(struct.pack("<" + fmt, v) for v in values)
    bits = struct.calcsize(fmt) * 8
    tags = [(256, 4, [width]), (257, 4, [height]), (258, 3, [bits] * samples), (259, 3, [compression]),
            (262, 3, [2 if samples == 3 else 1]), (273, 4, [0]), (277, 3, [samples]), (278, 4, [height]),
            (279, 4, [len(strip)]), (284, 3, [1]), (339, 3, [sample_format] * samples)]
    ifd_size = 2 + 12 * len(tags) + 4
    extra = b""
    entries = b""
    base = 8 + ifd_size
    for tag, kind, vals in tags:
        packed = b"".join(struct.pack("<H" if kind == 3 else "<I", v) for v in vals)
        if len(packed) <= 4:
            entries += struct.pack("<HHI", tag, kind, len(vals)) + packed.ljust(4, b"\0")
        else:
            entries += struct.pack("<HHII", tag, kind, len(vals), base + len(extra))
            extra += packed
    strip_at = base + len(extra)
    entries = entries.replace(struct.pack("<HHII", 273, 4, 1, 0), struct.pack("<HHII", 273, 4, 1, strip_at))
    return b"II*\0" + struct.pack("<I", 8) + struct.pack("<H", len(tags)) + entries + b"\0\0\0\0" + extra + strip


def depth_files():
    write("depth", "depth_4x3", b"\x01" + png16(4, 3, [800, 801, 0, 802, 799, 800, 805, 0, 790, 800, 801, 802]))
    depth = [800.0, 801.5, float("nan"), 802.0, 799.0, 0.0, 805.0, 800.5, 790.0, 800.0, 801.0, 3.4e38]
    write("depth", "tiff_float_4x3", b"\x03" + tiff(4, 3, 1, "f", 3, depth))
    write("depth", "tiff_uint16_deflate", b"\x03" + tiff(4, 3, 1, "H", 1, None, compression=8,
          payload=zlib.compress(b"".join(struct.pack("<H", v) for v in [800, 801, 0, 802] * 3))))
    points = [c for u, v in [(0, 0), (1, 0), (0, 1), (1, 1)] for c in ((u - 2) * 0.8, (v - 1.5) * 0.8, 400.0)]
    write("depth", "tiff_points_2x2", b"\x03" + tiff(2, 2, 3, "d", 3, points))
    write("depth", "camera", b"\x00" + b'{"fx": 500, "fy": 500, "cx": 2, "cy": 1.5, "depth_scale": 0.1,'
          b' "width": 4, "height": 3}')
    write("depth", "camera_open3d", b"\x00" + b'{"width": 4, "height": 3, "intrinsic_matrix": [500, 0, 0, 0, 500, 0, 2, 1.5, 1]}')
    write("depth", "camera_opencv", b"\x00" + b'{"camera_matrix": {"rows": 3, "cols": 3, "data": [[500, 0, 2], [0, 500, 1.5], [0, 0, 1]]}}')
    write("depth", "scene_camera", b"\x00" + b'{"1": {"cam_K": [500, 0, 2, 0, 500, 1.5, 0, 0, 1],'
          b' "depth_scale": 1.0}, "2": {"cam_K": [1, 0, 0, 0, 1, 0, 0, 0, 1], "depth_scale": 0.5}}')


def mesh_files():
    stl = "solid seed\n" + "".join(
        "facet normal 0 0 1\nouter loop\n" + "".join("vertex {} {} {}\n".format(*TETRA[i]) for i in f)
        + "endloop\nendfacet\n" for f in FACES) + "endsolid seed\n"
    write("mesh", "tetra_ascii_stl", b"\x00" + stl.encode())
    binary = b"seed".ljust(80, b" ") + struct.pack("<I", len(FACES))
    binary += b"".join(struct.pack("<12fH", 0, 0, 1, *(c for i in f for c in TETRA[i]), 0) for f in FACES)
    write("mesh", "tetra_binary_stl", b"\x00" + binary)
    obj = "o seed\n" + "".join("v {} {} {}\n".format(*p) for p in TETRA) + "vn 0 0 1\n"
    obj += "".join("f {}//1 {}//1 {}//1\n".format(*(i + 1 for i in f)) for f in FACES)
    write("mesh", "tetra_obj", b"\x01" + obj.encode())
    off = "OFF\n4 4 0\n" + "".join("{} {} {}\n".format(*p) for p in TETRA)
    off += "".join("3 {} {} {}\n".format(*f) for f in FACES)
    write("mesh", "tetra_off", b"\x02" + off.encode())


def xyz_files():
    write("xyz", "plain", "".join(f"{x} {y} {z}\n" for x, y, z in TETRA))
    write("xyz", "csv_header_normals", "x,y,z,nx,ny,nz\n" + "".join(f"{x},{y},{z},0,0,1\n" for x, y, z in TETRA))
    write("xyz", "comment_header_rgb", "//X;Y;Z;R;G;B\n" + "".join(f"{x};{y};{z};200;10;30\n" for x, y, z in TETRA))
    write("xyz", "pts_count_nan", "5\n" + "".join(f"{x}\t{y}\t{z}\t0.5\n" for x, y, z in TETRA) + "nan nan nan 0\n")
    rows = [(u, v) for v in range(4) for u in range(5)]  # a small depth image in its camera's frame
    write("xyz", "image", "".join(f"{(u - 2) / 500 * 800:.4f} {(v - 1.5) / 500 * 800:.4f} 800\n" for u, v in rows))


def bpdb_files(binpose):
    path = os.path.join(HERE, "corpus", "box.tmp")
    subprocess.run([binpose, "train", "--model", "builtin:box", "--out", path, "--points", "16",
                    "--d-dist", "10", "--d-angle", "30"], check=True, stdout=subprocess.DEVNULL)
    with open(path, "rb") as f:
        write("bpdb", "box_16_points", f.read())
    os.remove(path)


if __name__ == "__main__":
    ply_files()
    pcd_files()
    depth_files()
    mesh_files()
    xyz_files()
    if len(sys.argv) > 1:
        bpdb_files(sys.argv[1])
