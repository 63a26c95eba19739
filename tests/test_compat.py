import pytest

from lerobot_physvla.compat import UnsupportedLerobot, check_lerobot_version


def test_supported_version_passes_and_others_name_the_fix():
    check_lerobot_version()  # the installed one
    with pytest.raises(UnsupportedLerobot, match=r"found 0\.5\.0: pip install 'lerobot\[libero\]==0\.6\.1'"):
        check_lerobot_version("0.5.0")
