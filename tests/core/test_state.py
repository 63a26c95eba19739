import numpy as np
import pytest

from lerobot_physvla.core.state import PhysState, n_joints_from_size, packed_size

from conftest import make_state


def test_pack_unpack_round_trip():
    st = make_state(batch_size=3, lift=0.05)
    back = PhysState.unpack(st.pack())
    for name in ("eef_pos", "obj_pos", "obj_rest_z", "M", "J_pos", "tau", "dt"):
        np.testing.assert_array_equal(getattr(back, name), getattr(st, name))
    assert (back.valid == 1.0).all()
    assert st.pack().shape == (3, packed_size(7))


def test_sizes_identify_the_joint_count():
    for n in (4, 6, 7, 9):
        assert n_joints_from_size(packed_size(n)) == n
    with pytest.raises(ValueError, match="matches no arm"):
        n_joints_from_size(5)


def test_fields_are_views_until_rebound():
    st = make_state(batch_size=2)
    flat = st.pack()
    st.M[0, 0, 0] = 42.0
    assert st.pack() is flat and 42.0 in flat[0]
    st.M = np.zeros_like(st.M)  # rebinding detaches the buffer
    assert st.pack() is not flat and np.nanmax(st.pack()[0]) < 42.0


def test_empty_is_invalid_and_nonfinite_is_detected():
    st = PhysState.empty(2, 7)
    assert not st.valid.any()
    st2 = make_state(batch_size=2)
    st2.M[1, 0, 0] = np.nan
    assert st2.is_finite().tolist() == [True, False]
