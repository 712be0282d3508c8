"""The library keeps working and loses nothing when its cache is damaged or cannot be written, when processes write it
at once, when a Dask worker dies mid-sweep, on Ctrl-C in long work, and when the GPU is lost or asked for too much
(tests/faults.py provokes each for real; docs/reliability.md lists the outcomes, `make reliability`). The GPU's
faults are tested with the other GPU tests (test_gpu.py), which need an adapter."""

from __future__ import annotations

import faults


def test_a_damaged_cache_entry_is_rebuilt_never_read():
    rows = faults.cache_corruption()
    assert len(rows) == 2 * len(faults.DAMAGE)
    for what, damage, same, intact in rows:
        assert same and intact, f"{what}, {damage}: results unchanged {same}, entry rebuilt {intact}"


def test_an_unwritable_or_full_cache_computes_in_memory_and_warns_once():
    for name, run in faults.unwritable_cache().items():
        assert run["same"], name
        assert len(run["warnings"]) == 1 and "could not write its cache" in run["warnings"][0], (name, run["warnings"])
        assert run["left behind"] == [], name


def test_concurrent_writers_get_the_same_bits_and_one_intact_entry():
    for who, run in faults.concurrent_writers().items():
        assert run == {"same": True, "files": 1, "intact": True, "left behind": 0}, (who, run)


def test_a_sweep_survives_a_killed_dask_worker_bit_for_bit():
    run = faults.lost_worker()
    assert run == {"killed": True, "completed": True, "same": True}, run


def test_ctrl_c_stops_long_work_within_a_second_and_caches_nothing():
    for what, run in faults.interrupts().items():
        assert run["raised"] and run["seconds"] < 1.0, (what, run)
        assert run.get("left behind", []) == [], (what, run)
