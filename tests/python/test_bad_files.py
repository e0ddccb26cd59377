"""Hostile files found by fuzzing the loaders: refused with a ValueError, never a crash or a huge allocation."""
import struct

import pytest


def test_pc2_with_no_points_and_a_billion_frames_is_refused(core, tmp_path):
    path = tmp_path / "empty.pc2"
    path.write_bytes(b"POINTCACHE2\0" + struct.pack("<iiffi", 1, 0, 0.0, 1.0, 1_000_000_000))
    with pytest.raises(ValueError):
        core.read_pc2(str(path))


def test_pc2_whose_counts_overflow_is_refused(core, tmp_path):
    path = tmp_path / "huge.pc2"
    path.write_bytes(b"POINTCACHE2\0" + struct.pack("<iiffi", 1, 2_000_000_000, 0.0, 1.0, 2_000_000_000) + b"\0" * 64)
    with pytest.raises(ValueError):
        core.read_pc2(str(path))


def test_glb_whose_json_is_not_utf8_is_refused_with_a_message(core, tmp_path):
    """tinygltf quotes the bytes it stopped at; they used to make the ValueError's message empty (the
    translator handed Python a message that was not UTF-8). Undecodable bytes now read as U+FFFD."""
    content = b'{"as\xff\xfe": {"version": "2.0"}}'
    content += b" " * (-len(content) % 4)
    glb = b"glTF" + struct.pack("<II", 2, 20 + len(content)) + struct.pack("<I", len(content)) + b"JSON" + content
    path = tmp_path / "not_utf8.glb"
    path.write_bytes(glb)
    with pytest.raises(ValueError) as caught:
        core.load_character(str(path))
    assert "not a valid glTF file" in str(caught.value), repr(str(caught.value))
