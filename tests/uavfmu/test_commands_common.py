"""Options the commands share."""

from __future__ import annotations

from uavfmu.commands import excite, excite_quadrotor
from uavfmu.commands.common import comma_list, or_default


def test_comma_list_drops_blanks_and_spaces():
    assert comma_list(" roll, pitch,,yaw ,") == ("roll", "pitch", "yaw")
    assert comma_list(None) == () and comma_list("  ") == ()


def test_or_default_keeps_a_given_zero():
    assert or_default(0.0, 50.0) == 0.0 and or_default(None, 50.0) == 50.0


def test_both_excite_commands_report_one_exit_status():
    assert excite_quadrotor.EXIT_ILL_CONDITIONED is excite.EXIT_ILL_CONDITIONED == 3
    assert excite_quadrotor.EXIT_BAD_INPUT == excite.EXIT_BAD_INPUT == 2
