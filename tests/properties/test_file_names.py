"""Names that become paths: one rule, on both sides of the ptv/simulator wall."""

import pytest
from hypothesis import given
from hypothesis import strategies as st

from ptv import names
from simulator import rigs

NAME_LIKE = st.text(alphabet=st.sampled_from("aZ09._-/ \\ü:~"), max_size=70)


@given(name=NAME_LIKE | st.text(max_size=70))
def test_the_simulator_and_ptv_accept_the_same_names(name):
    assert rigs.is_file_name(name) == names.is_file_name(name)


@given(name=NAME_LIKE)
def test_an_accepted_name_stays_inside_its_folder(name, tmp_path_factory):
    if names.is_file_name(name):
        folder = tmp_path_factory.getbasetemp()
        assert (folder / name).resolve().parent == folder.resolve()
        assert not name.startswith(".")


@pytest.mark.parametrize("name", ["cam1", "C", "left-cam_2.v3", "9" * 64])
def test_plain_names_are_accepted(name):
    assert names.check_file_name(name, "camera") == name


@pytest.mark.parametrize("name", ["", "../x", "/tmp/x", ".hidden", "a/b", "a b", "é", "9" * 65, 7])
def test_names_that_could_point_elsewhere_are_refused(name):
    with pytest.raises(ValueError, match="camera: expected 1 to 64 letters"):
        names.check_file_name(name, "camera")
