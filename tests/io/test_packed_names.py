"""PackedNames: the reader's file names in one buffer."""

import pytest

from longslam.io.sequence.reader import PackedNames


def test_packed_names_give_back_each_name_in_order():
    names = ["rgb/0.000000.png", "rgb/0.100000.png", "depth/été.png", ""]
    packed = PackedNames(names)
    assert len(packed) == 4
    assert list(packed) == names
    assert packed[-2] == "depth/été.png" and packed[1:3] == names[1:3]
    assert set(PackedNames(names[:2])) | set(packed) == set(names)
    with pytest.raises(IndexError):
        packed[4]
