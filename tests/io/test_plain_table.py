"""plain_table: the one-pass read of a whitespace table, and the texts it leaves to the line parser."""

import numpy as np
import pytest

from longslam.io.plain_table import plain_table
from longslam.io.trajectory_files import read_tum


def test_a_plain_table_is_read_with_its_comments_and_blank_lines_skipped():
    text = "# t x\n1.5 2\n\n  # indented comment\n3 -4e-3\n"
    np.testing.assert_array_equal(plain_table(text, 2), [[1.5, 2.0], [3.0, -4e-3]])
    names = plain_table("0.1 rgb/é.png\n0.2\trgb/b.png\n", 2, str)
    assert names.tolist() == [["0.1", "rgb/é.png"], ["0.2", "rgb/b.png"]]


@pytest.mark.parametrize("text", [
    "1 2\n3 4 # a note after the data\n",  # a comment loadtxt would cut and the line parser refuses
    "1,2\n3,4\n",  # commas: the trajectory parser reads them as spaces
    "1 2\r\n3 4\r\n",  # a line break other than \n
    "1\u00a02\n",  # a space str.split splits on and loadtxt does not
    "1 2\n3\n",  # a short line
    "1 x\n",  # a word where a number goes
    "# only comments\n",
    "",
])
def test_anything_but_a_plain_table_goes_to_the_line_parser(text):
    assert plain_table(text, 2) is None


def test_a_trajectory_reads_the_same_either_way(tmp_path):
    rng = np.random.default_rng(3)
    rows = np.column_stack([np.arange(50) * 0.1, rng.normal(size=(50, 3)), rng.normal(size=(50, 4))])
    lines = [" ".join(repr(float(v)) for v in row) for row in rows]
    plain, commas = tmp_path / "plain.txt", tmp_path / "commas.txt"
    plain.write_text("# t tx ty tz qx qy qz qw\n" + "\n".join(lines) + "\n")
    commas.write_text("\n".join(line.replace(" ", ",") for line in lines) + "\n")  # the line parser's path
    a, b = read_tum(plain), read_tum(commas)
    np.testing.assert_array_equal(a.timestamps, b.timestamps)
    np.testing.assert_array_equal(a.poses, b.poses)
    root = a.timestamps
    while root.base is not None:
        root = root.base
    assert root.size == len(a.timestamps)  # its own array, not a view that keeps the whole table alive
