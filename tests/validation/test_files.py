"""Output folders are checked before any work."""

import pytest

from validation.files import check_output_folder


def test_output_folders_that_cannot_be_written_are_refused_by_name(tmp_path):
    a_file = tmp_path / "results.txt"
    a_file.write_text("not a folder")
    with pytest.raises(ValueError, match=r"--out .*results.txt is a file"):
        check_output_folder(a_file)
    with pytest.raises(ValueError, match=r"lies under .*results.txt, which is a file"):
        check_output_folder(a_file / "run" / "deeper")
    assert check_output_folder(tmp_path / "new" / "run") == tmp_path / "new" / "run"
    assert not (tmp_path / "new").exists()  # checked, not created
