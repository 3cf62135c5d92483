"""Every file reader parses its file or refuses it with a declared error that names the file (issue 20).

Each reader is fuzzed with Hypothesis over 10,000 examples: inputs made from scratch (random bytes, or
soups of the format's own tokens and hostile ones) and small valid files made here, mutated (bytes
flipped, cut short, tokens inserted or replaced by huge numbers, NaN, inf, 2**70, booleans, lines
dropped or repeated, emptied). Every example must either give a valid object or raise an
:class:`~faceanim.errors.InputError` whose message holds the file's path; any other exception fails the
test, and the message must be one line. Example-based tests beside each fuzz test pin the cases the
issue's probe and these fuzzers found.

Readers and their examples: read_fap, read_mesh on .obj, on .obj.gz, an OBJ's MTL and texture,
target_from_json, target_from_fdp, read_pairs, read_vertex_mask, read_parts_file, read_glb_json (with
glb_extras), Track.load: 10,000 examples each, 110,000 in all, zero undeclared errors. Each example is
one draw of bytes (see :func:`files`), which keeps Hypothesis's own cost near its floor.
"""

import gzip
import io
import json
import pickle
import re
import struct
from pathlib import Path

import numpy as np
import pytest
from conftest import grid_mesh, shared
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from faceanim.capture.track import Track
from faceanim.errors import FileFormatError, InputError
from faceanim.geometry import Mesh, read_mesh
from faceanim.geometry.meshio import glb_extras, read_glb_json
from faceanim.mpeg4 import FAP_COUNT
from faceanim.mpeg4.fapfile import read_fap
from faceanim.mpeg4.fapstream import FapStream
from faceanim.parts.labels import read_parts_file
from faceanim.pipeline import read_pairs, read_vertex_mask
from faceanim.target import Target, target_from_fdp, target_from_json

EXAMPLES = 10_000
# tmp_path is shared by a test's examples (each overwrites its file); too_slow can fire on a busy machine
fuzz = settings(max_examples=EXAMPLES, deadline=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])

# ---- inputs: from scratch and mutated

HOSTILE = ("", "0", "-0", "-1", "1.5", "0.5", "1e30", "-1e30", "1e300", "1e400", "-1e400", "nan", "NaN", "-nan",
           "inf", "-inf", "Infinity", "-Infinity", str(2**31), str(2**53 + 1), str(2**63), str(2**70), "9" * 5000,
           "true", "false", "null", "[]", "{}", '"x"', "[[0, 1]]", "\x00", "\xff", "\u00e9", "\u2028", "#", "\n",
           "\r", " ", "\t", "/", "//", ".", "..", "-", "0x10", "1_0", "\ufeff")
TOKEN = re.compile(rb"[^\s\[\]{},:\"=<>/]+")


def _encode(text: str) -> bytes:
    return text.encode("utf-8", "surrogatepass")


KINDS = ("flip", "cut", "insert", "replace", "replace", "drop line", "repeat line", "empty")


def _mutate(seed: bytes, program: bytes, words: tuple[bytes, ...]) -> bytes:
    """``seed`` changed by ``program``: four bytes per change (kind, position in two bytes, argument)."""
    data = bytearray(seed)
    for k in range(0, len(program) - 3, 4):
        kind, position, argument = KINDS[program[k] % len(KINDS)], program[k + 1] << 8 | program[k + 2], program[k + 3]
        word = words[argument % len(words)]
        if kind == "empty":
            data = bytearray()
        elif not data:
            data += word
        elif kind == "flip":
            data[position % len(data)] = argument
        elif kind == "cut":
            del data[position % len(data):]
        elif kind == "insert":
            at = position % (len(data) + 1)
            data[at:at] = word
        elif kind == "replace":
            spans = [m.span() for m in TOKEN.finditer(data)]
            if spans:
                a, b = spans[position % len(spans)]
                data[a:b] = word
        else:
            lines = bytes(data).split(b"\n")
            at = position % len(lines)
            lines[at:at + 1] = [] if kind == "drop line" else [lines[at], lines[at]]
            data = bytearray(b"\n".join(lines))
    return bytes(data)


def mutation(seeds: tuple[bytes, ...], tokens: tuple[str, ...] = ()):
    """``program -> bytes``: one of ``seeds`` (picked by the first byte) changed up to four times, four
    bytes a change: bytes flipped, cut short, a token inserted or put in place of one of the file's (the
    format's own tokens and :data:`HOSTILE` ones), a line dropped or repeated, everything emptied."""
    words = tuple(_encode(t) for t in tokens + HOSTILE)
    return lambda program: _mutate(seeds[program[0] % len(seeds)] if program else seeds[0], program[1:17], words)


def token_soup(tokens: tuple[str, ...], separators=(" ", " ", "\n")):
    """``program -> bytes``: the format's tokens, hostile tokens and separators, one per byte, in any order."""
    pieces = tokens + HOSTILE + separators
    assert len(pieces) <= 256
    return lambda program: _encode("".join(pieces[x % len(pieces)] for x in program[:60]))


def files(*makers):
    """File contents from one draw of bytes per example: the first byte picks one of ``makers``
    (functions of the remaining bytes), the rest is its program. One draw keeps Hypothesis's cost per
    example near its floor, and shrinking still leads to short programs: fewer changes, fewer bytes."""
    def make(program: bytes) -> bytes:
        return makers[program[0] % len(makers)](program[1:]) if program else makers[0](b"")

    return st.binary(max_size=300).map(make)


def inputs(seeds: tuple[bytes, ...], tokens: tuple[str, ...]):
    """Half the time a mutated valid file, else random bytes or a soup of tokens."""
    mutated = mutation(seeds, tokens)
    return files(mutated, mutated, bytes, token_soup(tokens))


def refused_or_read(read, path: Path, *named: Path):
    """``read(path)``, or None where it raises an InputError naming ``path`` (or one of ``named``).

    Any other exception propagates, and fails the test."""
    try:
        return read(path)
    except InputError as exc:
        message = str(exc)
        assert any(str(p) in message for p in (path, *named)), f"the message names no file: {message}"
        assert "\n" not in message, f"the message is not one line: {message}"
        return None


def put(path: Path, data: bytes) -> None:
    """Write ``data`` over the file at ``path`` in place: opening with truncation frees the file's blocks
    each time, which on an ext4 mounted with ``discard`` costs a quarter of a millisecond an example."""
    with open(path, "r+b" if path.exists() else "wb") as handle:
        handle.write(data)
        handle.truncate()


def gz(data: bytes) -> bytes:
    return gzip.compress(data, compresslevel=1, mtime=0)


# ---- .fap

def _fap_seeds() -> tuple[bytes, ...]:
    viseme = " ".join(["1", "1", "1"] + ["0"] * 45 + ["1"] + ["0"] * 19)
    hello = (f"2.1 hello 25 2\n{viseme}\n0 1 10 63 0 1 40 0 0 1 0 200 5000\n# a comment between frames\n"
             f"{viseme}\n1 10 1 32 0 1 20 0 0 0 0 150 2500.5\n")
    rng = np.random.default_rng(0)
    lines = ["2.1 plain 30 3"]
    for t in range(3):  # low-level FAPs only, about 7 a frame
        mask = rng.random(FAP_COUNT) < 0.1
        mask[:2] = False
        values = rng.integers(-300, 300, mask.sum())
        lines += [" ".join("1" if m else "0" for m in mask), " ".join(str(v) for v in [t, *values])]
    spaced = "2.1 C:\\Work\\a name with spaces 25 1\n" + " ".join(["0", "0", "1"] + ["0"] * 65) + "\n7 12\n"
    return hello.encode(), ("\n".join(lines) + "\n").encode(), spaced.encode(), b"2.1 none 25 0\n"


FAP_TOKENS = ("2.1", "25", "0", "1", "10", "#", "1e30", "63")


def valid_stream(stream: FapStream) -> None:
    assert len(stream) >= 1 and stream.mask.shape == (len(stream), FAP_COUNT) and stream.mask.dtype == bool
    assert np.isfinite(stream.values).all() and np.isfinite(stream.fps) and stream.fps > 0
    assert stream.frame_numbers.dtype == np.int64 and (stream.frame_numbers >= 0).all()
    assert (np.diff(stream.frame_numbers) >= 0).all()


@fuzz
@given(data=inputs(_fap_seeds(), FAP_TOKENS))
def test_read_fap_10000_examples_zero_undeclared_errors(tmp_path, data):
    """read_fap over 10,000 generated files: each reads as a valid FapStream or is refused by name."""
    path = tmp_path / "fuzz.fap"
    put(path, data)
    stream = refused_or_read(read_fap, path)
    if stream is not None:
        valid_stream(stream)


MASK = " ".join(["0", "0", "1"] + ["0"] * 65)


def test_whole_fap_frame_numbers_written_as_decimals_still_read(tmp_path):
    path = tmp_path / "a.fap"
    path.write_text(f"2.1 a 25 2\n{MASK}\n0.0 5\n{MASK}\n3.0 6\n")
    assert read_fap(path).frame_numbers.tolist() == [0, 3]


def test_xface_faps_read_as_valid_streams():
    for name in ("joy", "test"):
        valid_stream(read_fap(shared("xface", "Faps", f"{name}.fap")))


# ---- OBJ and .obj.gz

OBJ = b"""# a quad, a pentagon, negative indices and a UV seam
mtllib none.mtl
o face
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 2 0.5 0
v 2 1 0 0.5 0.5 0.5
vt 0 0
vt 1 0
vt 1 1
vt 0 1
vt 0.5 0.5
vn 0 0 1
usemtl skin
f 1/1/1 2/2/1 3/3/1 4/4/1
usemtl lips
f -5/5 -2/1 -1/2 3/3 -3/4
g teeth
f 1//1 2//1 5//1
"""
PLAIN_OBJ = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 1e-3\nf 1 2 3\nf 2 4 3\n"
OBJ_TOKENS = ("v", "vt", "vn", "f", "usemtl", "mtllib", "o", "g", "s", "1", "2", "3", "-1", "-7", "0", "1/1", "1//1",
              "1/1/1", "0.5", "skin", "none.mtl")


def valid_mesh(mesh: Mesh) -> None:
    assert len(mesh.vertices) >= 1 and len(mesh.triangles) >= 1
    assert np.isfinite(mesh.vertices).all()
    assert mesh.triangles.min() >= 0 and mesh.triangles.max() < len(mesh.vertices)
    if mesh.uv is not None:
        assert np.isfinite(mesh.uv).all() and mesh.uv_triangles.shape == mesh.triangles.shape


@fuzz
@given(data=inputs((OBJ, PLAIN_OBJ), OBJ_TOKENS))
def test_read_mesh_obj_10000_examples_zero_undeclared_errors(tmp_path, data):
    """read_mesh on .obj over 10,000 generated files: a valid Mesh or a refusal naming the file."""
    path = tmp_path / "fuzz.obj"
    put(path, data)
    mesh = refused_or_read(read_mesh, path)
    if mesh is not None:
        valid_mesh(mesh)


@fuzz
@given(data=files(mutation((gz(OBJ), gz(PLAIN_OBJ)), ("\x1f\x8b",)),
                  lambda p: gz(mutation((OBJ, PLAIN_OBJ), OBJ_TOKENS)(p)), bytes,
                  lambda p: gz(token_soup(OBJ_TOKENS)(p))))
def test_read_mesh_obj_gz_10000_examples_zero_undeclared_errors(tmp_path, data):
    """read_mesh on .obj.gz over 10,000 generated files (broken gzip and broken OBJ inside good gzip):
    a valid Mesh or a refusal naming the file."""
    path = tmp_path / "fuzz.obj.gz"
    put(path, data)
    mesh = refused_or_read(read_mesh, path)
    if mesh is not None:
        valid_mesh(mesh)


@pytest.mark.parametrize("data, match", [
    (gz(PLAIN_OBJ)[:-12], r"fuzz.obj.gz: is not a complete gzip file"),
    (gz(PLAIN_OBJ)[:25], r"fuzz.obj.gz: is not a complete gzip file"),
    (PLAIN_OBJ, r"fuzz.obj.gz: is not a gzip file"),
    (gz(PLAIN_OBJ)[:12] + b"\x00" * 20 + gz(PLAIN_OBJ)[32:], r"fuzz.obj.gz: is not a readable gzip file"),
    (gz(b"v 0 0 0\xff\n"), r"fuzz.obj.gz: is not a text OBJ file"),
    (b"v 0 0 1e400\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", r"fuzz.obj.gz: is not a gzip file"),
], ids=["no trailer", "cut in the data", "text", "corrupt data", "not UTF-8", "text with 1e400"])
def test_broken_obj_gz_is_refused_by_name(tmp_path, data, match):
    path = tmp_path / "fuzz.obj.gz"
    put(path, data)
    with pytest.raises(FileFormatError, match=match):
        read_mesh(path)


@pytest.mark.parametrize("text, match", [
    ("v 0 0 1e400\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", r"a.obj:1: vertex has a non-finite coordinate"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt nan 0\nf 1/1 2/1 3/1\n", r"a.obj:4: texture coordinate has a non-finite"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 " + str(2**70) + "\n", r"a.obj:4: vertex index 1180591620717411303424 is"),
    ("v\t0\t0\t0\nv 1 0 0\nv 0 1 0\nf\t1 2 3\n", None),
])
def test_obj_lines_the_probe_found(tmp_path, text, match):
    path = tmp_path / "a.obj"
    path.write_text(text)
    if match is None:  # tabs separate fields, as OBJ allows
        assert len(read_mesh(path).vertices) == 3
        return
    with pytest.raises(FileFormatError, match=match):
        read_mesh(path)


def test_ict_obj_gz_files_read():
    for name in ("jawOpen", "identity000"):
        path = shared("ict_facekit", "obj", f"{name}.obj.gz")
        valid_mesh(read_mesh(path))


# ---- MTL and its texture

TEXTURED_OBJ = b"mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nusemtl skin\nf 1/1 2/2 3/3\n"
MTL = b"newmtl skin\nKd 1 1 1\nmap_Kd t.png\n# two\nnewmtl other\nmap_Kd -s 1 1 1 t.png\n"
MTL_TOKENS = ("newmtl", "map_Kd", "skin", "other", "t.png", "m.mtl", "fuzz.obj", "Kd", "-s")


def _image_seeds() -> tuple[bytes, ...]:
    from PIL import Image

    rng = np.random.default_rng(0)
    seeds = []
    for mode, fmt in (("RGB", "PNG"), ("RGBA", "PNG"), ("L", "PNG"), ("P", "PNG"), ("I;16", "PNG"), ("RGB", "JPEG"),
                      ("CMYK", "JPEG"), ("RGB", "BMP"), ("P", "GIF"), ("1", "PNG")):
        image = Image.fromarray(rng.integers(0, 255, size=(3, 5, 3), dtype=np.uint8)).convert(mode)
        out = io.BytesIO()
        image.save(out, format=fmt)
        seeds.append(out.getvalue())
    return tuple(seeds)


IMAGES = _image_seeds()


def png_header(width: int, height: int) -> bytes:
    """A PNG that declares ``width`` x ``height`` pixels (no image data: only its header is read)."""
    import zlib

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    chunk = struct.pack(">I", len(ihdr)) + b"IHDR" + ihdr + struct.pack(">I", zlib.crc32(b"IHDR" + ihdr))
    return b"\x89PNG\r\n\x1a\n" + chunk + b"\x00\x00\x00\x00IEND\xaeB`\x82"


LARGE_IMAGES = (png_header(40000, 40000), png_header(20000, 2), png_header(9500, 9500), png_header(16384, 1))


@fuzz
@given(mtl=files(lambda p: MTL, mutation((MTL,), MTL_TOKENS), bytes, token_soup(MTL_TOKENS)),
       image=files(mutation(IMAGES, ("\x89PNG",)), mutation(IMAGES, ("\x89PNG",)), bytes,
                   lambda p: (IMAGES + LARGE_IMAGES)[p[0] % (len(IMAGES) + len(LARGE_IMAGES))] if p
                   else IMAGES[0]))
def test_read_obj_texture_10000_examples_zero_undeclared_errors(tmp_path, mtl, image):
    """An OBJ's MTL and map_Kd image over 10,000 generated pairs: a Mesh (with or without its texture) or a
    refusal naming the MTL and the image."""
    obj, mtl_path, image_path = tmp_path / "fuzz.obj", tmp_path / "m.mtl", tmp_path / "t.png"
    if not obj.exists():
        obj.write_bytes(TEXTURED_OBJ)
    put(mtl_path, mtl)
    put(image_path, image)
    mesh = refused_or_read(read_mesh, obj, mtl_path)
    if mesh is not None:
        valid_mesh(mesh)
        assert mesh.texture is None or (mesh.texture.dtype == np.uint8 and mesh.texture.shape[2] == 3)


@pytest.mark.parametrize("image, match", [
    (b"this is no image", r"m.mtl: texture .*t.png is not an image"),
    (png_header(40000, 40000), r"m.mtl: texture .*t.png is too large \(Image size \(1600000000 pixels\) exceeds"),
    (png_header(20000, 2), r"m.mtl: texture .*t.png is 20000 x 2 pixels; textures may be at most 16384 pixels a"),
    (png_header(9500, 9500), r"m.mtl: texture .*t.png is 9500 x 9500 pixels; .* and 89,478,485 pixels in all"),
    (IMAGES[0][:60], r"m.mtl: texture .*t.png cannot be decoded"),
], ids=["text", "40000 x 40000", "20000 x 2", "9500 x 9500", "cut short"])
def test_bad_texture_is_refused_naming_mtl_and_image(tmp_path, image, match):
    (tmp_path / "a.obj").write_bytes(TEXTURED_OBJ)
    (tmp_path / "m.mtl").write_bytes(MTL)
    (tmp_path / "t.png").write_bytes(image)
    with pytest.raises(FileFormatError, match=match):
        read_mesh(tmp_path / "a.obj")


def test_materials_and_textures_that_are_absent_or_folders_are_left_out(tmp_path):
    for name, mtllib in (("a.obj", b"missing.mtl"), ("b.obj", b"."), ("c.obj", b"a" * 5000)):
        (tmp_path / name).write_bytes(TEXTURED_OBJ.replace(b"m.mtl", mtllib))
        assert read_mesh(tmp_path / name).texture is None
    (tmp_path / "d.obj").write_bytes(TEXTURED_OBJ)
    for image in (b"missing.png", b"."):
        (tmp_path / "m.mtl").write_bytes(b"newmtl skin\nmap_Kd " + image + b"\n")
        assert read_mesh(tmp_path / "d.obj").texture is None


def test_texture_is_read_relative_to_its_mtl(tmp_path):
    from PIL import Image

    (tmp_path / "sub").mkdir()
    (tmp_path / "a.obj").write_bytes(TEXTURED_OBJ.replace(b"m.mtl", b"sub/m.mtl"))
    (tmp_path / "sub" / "m.mtl").write_bytes(MTL)
    Image.new("RGB", (4, 2), (10, 20, 30)).save(tmp_path / "sub" / "t.png")
    assert read_mesh(tmp_path / "a.obj").texture.shape == (2, 4, 3)


# ---- points JSON and .fdp (a Target on a 9 x 9 grid)

GRID = grid_mesh(9, size=8.0)
POINTS = {"2.1": 4, "2.2": 22, "8.3": 24, "8.4": 20, "9.15": 40, "3.1": 61, "3.3": 52, "3.2": 55, "3.4": 46,
          "3.7": 62, "3.11": 59, "3.8": 57, "3.12": 54}
POINT_TOKENS = ("2.1", "8.3", "3.5", "points", "mp0", "4", "80", "81", "-3")


def valid_target(target: Target) -> None:
    assert target.points and all(isinstance(n, str) for n in target.points)
    assert all(type(i) is int and 0 <= i < len(GRID.vertices) for i in target.points.values())
    fapu = [target.fapu.irisd0, target.fapu.es0, target.fapu.ens0, target.fapu.mns0, target.fapu.mw0]
    assert np.isfinite(fapu).all() and min(fapu) > 0


@fuzz
@given(data=inputs((json.dumps(POINTS).encode(), json.dumps({"points": POINTS}, indent=1).encode()), POINT_TOKENS))
def test_target_from_json_10000_examples_zero_undeclared_errors(tmp_path, data):
    """target_from_json over 10,000 generated files: a valid Target or a refusal naming the file."""
    path = tmp_path / "fuzz.json"
    put(path, data)
    target = refused_or_read(lambda p: target_from_json(GRID, p), path)
    if target is not None:
        valid_target(target)


@pytest.mark.parametrize("points, match", [
    ({**POINTS, "8.3": True}, r"p.json: point '8.3' must name a vertex by its integer id, got true"),
    ({**POINTS, "8.3": 2**70}, r"p.json: point 8.3 names vertex 1180591620717411303424"),
    ({**POINTS, "8.3": 2.0}, r"p.json: point '8.3' must name a vertex by its integer id, got 2.0"),
])
def test_points_json_ids_the_probe_found(tmp_path, points, match):
    path = tmp_path / "p.json"
    path.write_text(json.dumps(points))
    with pytest.raises(InputError, match=match):
        target_from_json(GRID, path)


def test_json_readers_refuse_deep_nesting_and_bad_text(tmp_path):
    path = tmp_path / "p.json"
    path.write_text("[" * 100_000)
    with pytest.raises(FileFormatError, match="p.json: is not valid JSON"):
        target_from_json(GRID, path)
    path.write_bytes(b'{"8.3": \xff}')
    with pytest.raises(FileFormatError, match=r"p.json:1: is not UTF-8 text \(byte 0xff\)"):
        target_from_json(GRID, path)


def _fdp(fapu: bool = True) -> bytes:
    head = '  <head><fapu ENS0="3" ES0="4" IRISD0="1" MNS0="2" MW0="4"/></head>\n' if fapu else ""
    points = "".join(f'  <fdp affects="face" index="{i}" name="{n}">\n    <influence weight="0.5"/>\n  </fdp>\n'
                     for n, i in POINTS.items())
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n<xfdp>\n{head}{points}'
            '  <fdp affects="teeth" index="2" name="2.1"/>\n</xfdp>\n').encode()


FDP_TOKENS = ("xfdp", "fdp", "fapu", "head", "affects", "index", "name", "face", "teeth", "ES0", "<!DOCTYPE x>",
              "<!--", "-->", "&amp;", "&x;")


@fuzz
@given(data=inputs((_fdp(), _fdp(fapu=False)), FDP_TOKENS))
def test_target_from_fdp_10000_examples_zero_undeclared_errors(tmp_path, data):
    """target_from_fdp over 10,000 generated files: a valid Target or a refusal naming the file."""
    path = tmp_path / "fuzz.fdp"
    put(path, data)
    target = refused_or_read(lambda p: target_from_fdp(GRID, p), path)
    if target is not None:
        valid_target(target)


@pytest.mark.parametrize("old, new, match", [
    (b'ES0="4"', b'ES0="nan"', r"a.fdp: <fapu> must give IRISD0, ES0, ENS0, MNS0 and MW0 as positive numbers"),
    (b'ES0="4"', b'ES0="-4"', r"a.fdp: <fapu> must give"),
    (b'name="8.3"', b'', r"a.fdp: a feature point has no name"),
    (b'name="8.3"', b'name="lip"', r"a.fdp: unknown feature point 'lip'"),
    (b'index="24"', b'index="' + str(2**70).encode() + b'"', r"a.fdp: point 8.3 names vertex 1180591620717411303424"),
])
def test_fdp_values_the_fuzzer_found(tmp_path, old, new, match):
    path = tmp_path / "a.fdp"
    path.write_bytes(_fdp().replace(old, new))
    with pytest.raises(InputError, match=match):
        target_from_fdp(GRID, path)


def test_xface_fdp_still_reads():
    path = shared("xface", "Faces", "alice", "alice.fdp")
    big = Mesh(np.random.default_rng(0).normal(size=(6000, 3)), [[0, 1, 2]])
    assert len(target_from_fdp(big, path).points) == 32


# ---- pairs JSON and the vertex mask JSON of transfer

PAIRS = json.dumps({"source": [0, 1, 2, 5], "target": [3, 1, 0, 7]}).encode()
ID_TOKENS = ("source", "target", "0", "1", "7", "9", "10")


@fuzz
@given(data=inputs((PAIRS,), ID_TOKENS))
def test_read_pairs_10000_examples_zero_undeclared_errors(tmp_path, data):
    """read_pairs over 10,000 generated files: paired int64 vertex ids or a refusal naming the file."""
    path = tmp_path / "fuzz.json"
    put(path, data)
    pairs = refused_or_read(read_pairs, path)
    if pairs is not None:
        source, target = pairs
        assert source.dtype == target.dtype == np.int64 and source.shape == target.shape and len(source) >= 1
        assert source.min() >= 0 and target.min() >= 0


@pytest.mark.parametrize("pairs, match", [
    ({"source": [0, 2**70], "target": [0, 1]}, r'pairs.json: "source" must be a list of integer vertex ids from 0'),
    ({"source": [0, -1], "target": [0, 1]}, r'pairs.json: "source" must be a list of integer vertex ids from 0'),
    ({"source": [True, 1], "target": [0, 1]}, r'pairs.json: "source" must be a list of integer vertex ids from 0'),
    ({"source": [], "target": []}, r"pairs.json: holds no pairs"),
])
def test_pair_ids_the_probe_found(tmp_path, pairs, match):
    path = tmp_path / "pairs.json"
    path.write_text(json.dumps(pairs))
    with pytest.raises(FileFormatError, match=match):
        read_pairs(path)


@fuzz
@given(data=inputs((b"[0, 1, 2, 7]", b"[]"), ID_TOKENS))
def test_read_vertex_mask_10000_examples_zero_undeclared_errors(tmp_path, data):
    """read_vertex_mask (transfer's --mask) over 10,000 generated files: a (10,) bool mask or a refusal
    naming the file."""
    path = tmp_path / "fuzz.json"
    put(path, data)
    mask = refused_or_read(lambda p: read_vertex_mask(p, 10), path)
    if mask is not None:
        assert mask.dtype == bool and mask.shape == (10,)


@pytest.mark.parametrize("text, match", [
    ("[true, false]", r"mask.json: must be a JSON list of target vertex ids in \[0, 10\)"),
    (f"[0, {2**70}]", r"mask.json: must be a JSON list of target vertex ids in \[0, 10\)"),
    ("[0, 1.0]", r"mask.json: must be a JSON list of target vertex ids"),
    ("[0, 1", r"mask.json:1: is not valid JSON"),
])
def test_vertex_mask_ids_the_probe_found(tmp_path, text, match):
    path = tmp_path / "mask.json"
    path.write_text(text)
    with pytest.raises(FileFormatError, match=match):
        read_vertex_mask(path, 10)


def test_vertex_mask_reads_ids(tmp_path):
    path = tmp_path / "mask.json"
    path.write_text("[0, 3, 3]")
    assert np.flatnonzero(read_vertex_mask(path, 5)).tolist() == [0, 3]


# ---- --parts JSON

PARTS = json.dumps({"teeth": ["M_Teeth"], "static": [[0, 5], "M_Hat"], "eye": []}).encode()
PARTS_TOKENS = ("teeth", "static", "eye", "skin", "M_Teeth", "0", "5")


@fuzz
@given(data=inputs((PARTS,), PARTS_TOKENS))
def test_read_parts_file_10000_examples_zero_undeclared_errors(tmp_path, data):
    """read_parts_file over 10,000 generated files: roles to names and ranges, or a refusal naming the file."""
    path = tmp_path / "fuzz.json"
    put(path, data)
    parts = refused_or_read(read_parts_file, path)
    if parts is not None:
        assert isinstance(parts, dict) and parts
        for entries in parts.values():
            for entry in entries:
                assert isinstance(entry, str) or (len(entry) == 2 and all(type(i) is int and i >= 0 for i in entry))


# ---- .glb's JSON chunk

def glb(document: bytes, *, declared: int | None = None) -> bytes:
    document += b" " * (-len(document) % 4)
    length = len(document) if declared is None else declared
    return (b"glTF" + struct.pack("<II", 2, 20 + len(document)) + struct.pack("<I", length) + b"JSON" + document)


GLB_SEEDS = (glb(b'{"asset": {"version": "2.0"}, "meshes": [{"extras": {"faceanim": {"metres_per_unit": 0.01}}}]}'),
             glb(b'{"meshes": []}'))


@fuzz
@given(data=files(mutation(GLB_SEEDS, ("meshes", "extras", "faceanim")), bytes,
                  lambda p: glb(token_soup(("glTF", "JSON", "{", "}", "meshes", "extras", "faceanim"))(p))))
def test_read_glb_json_10000_examples_zero_undeclared_errors(tmp_path, data):
    """read_glb_json and glb_extras over 10,000 generated files: a JSON object or a refusal naming the file."""
    path = tmp_path / "fuzz.glb"
    put(path, data)
    document = refused_or_read(read_glb_json, path)
    if document is not None:
        assert isinstance(document, dict)
        assert isinstance(glb_extras(path), dict)


def test_glb_json_that_is_no_object_is_refused(tmp_path):
    path = tmp_path / "a.glb"
    path.write_bytes(glb(b"[1, 2]"))
    with pytest.raises(FileFormatError, match="a.glb: its JSON chunk is not an object"):
        read_glb_json(path)
    path.write_bytes(glb(b"[" * 100_000))
    with pytest.raises(FileFormatError, match="a.glb: has a broken JSON chunk"):
        read_glb_json(path)
    path.write_bytes(glb(b'{"meshes": 5}'))
    assert glb_extras(path) == {}
    path.write_bytes(glb(b'{"meshes": []}', declared=400))
    with pytest.raises(FileFormatError, match="a.glb: is cut short"):
        read_glb_json(path)


# ---- .npz tracks

def _track(T=3, L=4) -> Track:
    rng = np.random.default_rng(0)
    landmarks = rng.random((T, L, 3))
    landmarks[1] = np.nan
    valid = np.array([True, False, True])
    return Track(landmarks, valid, np.zeros(T, bool), np.arange(T) / 25.0, 25.0, 64, 48, "v.mp4",
                 rng.random((T, 2)), ("jawOpen", "mouthSmile_L"))


def _saved(track: Track) -> dict:
    return {"landmarks": track.landmarks, "valid": track.valid, "filled": track.filled, "times": track.times,
            "fps": track.fps, "width": track.width, "height": track.height, "source": track.source,
            "blendshapes": track.blendshapes, "blendshape_names": np.array(track.blendshape_names)}


def _npz(arrays: dict, compressed: bool = True) -> bytes:
    out = io.BytesIO()
    (np.savez_compressed if compressed else np.savez)(out, **arrays)
    return out.getvalue()


WEIRD = (np.array([]), np.array(0.0), np.array(np.nan), np.array(np.inf), np.array(-1), np.array(1e300),
         np.array(2**62), np.array(-(2**62)), np.array("x"), np.array(True), np.array([1 + 2j]), np.zeros((3, 4)),
         np.zeros((0, 4, 3)), np.zeros((3, 4, 3), np.float32), np.full((3, 4, 3), np.nan), np.array([True, False]),
         np.zeros(3, np.int8), np.array(["a", "b"]), np.zeros((2, 2, 2, 2)), np.array([[1]]), np.ones(3, bool),
         np.zeros(3, "datetime64[s]"), np.zeros(3, [("a", "f8")]), np.array(b"bytes"), np.zeros((3, 2)),
         np.zeros((3, 0, 3)), np.array([np.inf, 0, 1]), np.array(25.5), np.array([25.0]), np.zeros(3, np.uint64) - 1)
SAVED = _saved(_track())


def _track_npz(program: bytes) -> bytes:
    """A ``.npz`` of the track's arrays, each kept, dropped or replaced by an odd one as ``program``'s
    byte for it says (0 keeps: shrinking leads back to the valid file); maybe an extra array."""
    arrays, program = {}, program.ljust(len(SAVED) + 2, b"\0")
    for (key, value), byte in zip(SAVED.items(), program, strict=False):
        if byte % 8 < 5:
            arrays[key] = value
        elif byte % 8 > 5:
            arrays[key] = WEIRD[byte // 8 % len(WEIRD)]
    extra, compressed = program[-2:]
    if extra % 2:
        arrays["extra"] = WEIRD[extra // 2 % len(WEIRD)]
    return _npz(arrays, compressed=bool(compressed % 2))


NPZ_SEEDS = (_npz(SAVED), _npz(SAVED, compressed=False))
_npy = io.BytesIO()
np.save(_npy, np.zeros((2, 3)))
NPY_SEEDS = (_npy.getvalue(), pickle.dumps({"landmarks": [1, 2]}), b"PK\x03\x04", b"PK\x05\x06" + b"\x00" * 18)


@fuzz
@given(data=files(_track_npz, _track_npz, mutation(NPZ_SEEDS + NPY_SEEDS, ("PK", "\x93NUMPY")), bytes))
def test_track_load_10000_examples_zero_undeclared_errors(tmp_path, data):
    """Track.load over 10,000 generated files (odd arrays, broken zips, .npy and pickles): a valid Track
    or a refusal naming the file."""
    path = tmp_path / "fuzz.npz"
    put(path, data)
    track = refused_or_read(Track.load, path)
    if track is not None:
        T = len(track.valid)
        assert T >= 1 and track.landmarks.ndim == 3 and track.landmarks.shape[0] == T
        assert track.landmarks.shape[1] >= 1 and track.landmarks.shape[2] == 3
        assert track.valid.dtype == track.filled.dtype == bool and track.filled.shape == (T,)
        assert track.times.shape == (T,) and np.isfinite(track.times).all()
        assert np.isfinite(track.fps) and track.fps > 0 and track.width >= 1 and track.height >= 1
        assert np.isfinite(track.landmarks[track.valid | track.filled]).all()
        if track.blendshapes is not None:
            assert track.blendshapes.shape == (T, len(track.blendshape_names))


def test_saved_track_loads_back(tmp_path):
    track = _track()
    track.save(tmp_path / "t.npz")
    back = Track.load(tmp_path / "t.npz")
    np.testing.assert_array_equal(back.landmarks, track.landmarks)
    assert back.blendshape_names == track.blendshape_names and back.width == 64 and back.source == "v.mp4"


def _patched(data: bytes, changes: dict) -> bytes:
    """``data`` with single bytes changed; negative offsets count from the zip's central directory."""
    out, central = bytearray(data), data.find(b"PK\x01\x02")
    for at, value in changes.items():
        out[at if at >= 0 else central + ~at] = value
    return bytes(out)


@pytest.mark.parametrize("data, match", [
    (b"", r"t.npz: is empty"),
    (_patched(NPZ_SEEDS[1], {8: 99, ~10: 99}), r"t.npz: is not a faceanim track \(NotImplementedError: That comp"),
    (_patched(NPZ_SEEDS[1], {6: 1, ~8: 1}), r"t.npz: is not a faceanim track \(RuntimeError: .* is encrypted"),
    (NPY_SEEDS[0], r"t.npz: is a single .npy array, not a faceanim track"),
    (NPY_SEEDS[1], r"t.npz: is not a faceanim track \(not a .npz file"),
    (NPZ_SEEDS[0][:100], r"t.npz: is not a faceanim track"),
    (_npz({**SAVED, "fps": np.array(np.inf)}), r"t.npz: is not a faceanim track \(fps must be"),
    (_npz({**SAVED, "width": np.array(1e300)}), r"t.npz: is not a faceanim track \(width must be"),
    (_npz({**SAVED, "valid": np.ones(2, bool)}), r"t.npz: is not a faceanim track \(valid must have shape \(3,\)"),
    (_npz({**SAVED, "valid": np.ones(3)}), r"t.npz: is not a faceanim track \(valid must be an array of booleans"),
    (_npz({**SAVED, "landmarks": SAVED["landmarks"] + 0j}), r"t.npz: is not a faceanim track \(landmarks must be an "),
    (_npz({k: v for k, v in SAVED.items() if k != "fps"}), r"t.npz: is not a faceanim track \(it lacks fps\)"),
], ids=["empty", "compression method", "encrypted", ".npy", "pickle", "cut short", "fps inf", "width 1e300",
        "valid short", "valid float", "complex landmarks", "no fps"])
def test_bad_tracks_the_probe_found(tmp_path, data, match):
    path = tmp_path / "t.npz"
    put(path, data)
    with pytest.raises(FileFormatError, match=match):
        Track.load(path)
