"""`hola_ray.clock`: a metrics row's account of where its time went."""

from __future__ import annotations

import time

import pytest

from hola_ray.clock import NAMES, PhaseClock, column, process_start


def test_an_account_adds_up_to_its_wall_time_and_starts_afresh():
    clock = PhaseClock(since=time.perf_counter() - 1.0)  # a second before it was made
    with clock.phase("grapher"):
        time.sleep(0.05)
    clock.add("oracle_update", 0.25)
    clock.add("oracle_update", 0.25)  # phases accumulate
    row = clock.close()
    assert row[column("grapher")] >= 0.05 and row[column("oracle_update")] == 0.5
    parts = sum(v for k, v in row.items() if k.startswith("time_"))
    assert row["wall_s"] >= 1.05 and parts == pytest.approx(row["wall_s"], abs=0.02)
    assert row[column("other")] > 0.4  # the second before, which no phase covered
    later = clock.close()  # a new account from the last close
    assert later["wall_s"] < 0.05 and set(later) == {"wall_s", column("other")}


def test_phases_are_the_documented_ones():
    clock = PhaseClock()
    with pytest.raises(ValueError, match="no phase 'judging'"):
        clock.add("judging", 1.0)
    with pytest.raises(ValueError, match="no phase 'other'"):
        clock.add("other", 1.0)  # what no phase covers is derived, never added
    assert NAMES[-1] == "other" and len(set(NAMES)) == len(NAMES)


def test_a_process_started_before_now():
    started = process_start()
    assert 0 < time.perf_counter() - started < 3600
