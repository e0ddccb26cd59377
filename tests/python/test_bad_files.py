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
