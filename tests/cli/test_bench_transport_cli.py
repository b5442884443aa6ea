"""``dptpu bench transport``: the report's structure and that every message arrived intact (tiny size).

The benchmark runs real process pairs over ipc (ours through ``dptpu.graph``, raw through bare pyzmq).
Timings and ratios are never asserted against goals here, only checked for consistency.
"""
from __future__ import annotations

import contextlib
import io
import json
import os

import pytest

from dptpu.cli import bench_cmd
from dptpu.cli.main import main

SMALL = {"shape": [2, 48, 64], "messages": 20, "rounds": 1, "round_trips": 50, "warmup_messages": 4,
         "warmup_round_trips": 20, "window": 4}


@pytest.fixture(scope="module")
def report():
    """The JSON report of one ``--size small`` run, with its exit code; the 6 kB messages go through shared memory
    (``DPTPU_SHM_MIN_BYTES`` 4096, the children inherit it), the ZeroMQ variant does not."""
    buffer = io.StringIO()
    before = os.environ.get("DPTPU_SHM_MIN_BYTES")
    os.environ["DPTPU_SHM_MIN_BYTES"] = "4096"
    try:
        with contextlib.redirect_stdout(buffer):
            code = main(["bench", "transport", "--json", "--size", "small"])
    finally:
        if before is None:
            del os.environ["DPTPU_SHM_MIN_BYTES"]
        else:
            os.environ["DPTPU_SHM_MIN_BYTES"] = before
    return code, json.loads(buffer.getvalue())


def test_exit_0_and_the_headline_keys(report):
    code, data = report
    assert code == 0  # 0 means every message of both variants arrived intact
    assert data["intact"] is True and data["transport"] == "ipc" and data["size"] == "small"
    for key in ("throughput_ratio", "latency_p50_ratio", "latency_p99_ratio", "raw_throughput_mb_per_s",
                "raw_latency_p50_us", "raw_latency_p99_us", "ours_throughput_mb_per_s", "ours_latency_p50_us",
                "ours_latency_p99_us"):
        assert data[key] > 0, key
    assert data["throughput_ratio"] == pytest.approx(data["ours_throughput_mb_per_s"] / data["raw_throughput_mb_per_s"])
    assert data["latency_p50_ratio"] == pytest.approx(data["ours_latency_p50_us"] / data["raw_latency_p50_us"])
    assert data["latency_p99_ratio"] == pytest.approx(data["ours_latency_p99_us"] / data["raw_latency_p99_us"])
    goals = data["goals"]
    assert (goals["throughput_ratio_min"], goals["latency_ratio_max"]) == (0.9, 2.0)
    assert goals["throughput_met"] == (data["throughput_ratio"] >= 0.9)
    assert data["machine"]["cores"] >= 1
    pinned = data["pinned"]  # default: senders and receivers on disjoint CPU halves (when there are >= 2)
    if pinned is not None:
        assert pinned["senders"] and pinned["receivers"]
        assert not set(pinned["senders"]) & set(pinned["receivers"])


@pytest.mark.parametrize("variant", ["ours", "raw"])
def test_every_throughput_message_arrived_intact_and_in_order(report, variant):
    throughput = report[1]["throughput"]
    assert throughput["shape"] == SMALL["shape"] and throughput["message_bytes"] == 2 * 48 * 64
    assert (throughput["messages_per_round"], throughput["rounds"], throughput["window"]) == (20, 1, 4)
    entry = throughput[variant]
    receiver = entry["receiver"]
    assert receiver["timed"] == 20  # every timed message, each checked on its sample
    assert receiver["full_checks"] >= 4  # warm-up messages compared bit for bit
    assert (receiver["failures"], receiver["sequence_gaps"]) == (0, 0)
    assert receiver["received"] == receiver["timed"] + receiver["full_checks"] + 1  # + the stop message
    assert entry["intact"] is True
    assert len(entry["rounds_mb_per_s"]) == 1 and entry["mb_per_s"] == entry["rounds_mb_per_s"][0]
    assert entry["messages_per_s"] == pytest.approx(entry["mb_per_s"] * 1e6 / (2 * 48 * 64))
    assert entry["sender_cpu_us_per_message"] >= 0
    if variant == "ours":
        assert receiver["dropped_count"] == 0


@pytest.mark.parametrize("variant", ["ours", "raw"])
def test_every_round_trip_came_back_with_its_payload(report, variant):
    latency = report[1]["latency"]
    assert latency["payload_bytes"] == 64 and latency["round_trips_per_round"] == 50
    entry = latency[variant]
    assert entry["round_trips"] == 50 and entry["intact"] is True
    assert entry["answered"] >= 50 + 20 + 1  # timed + warm-up + the stop message (probes may add more)
    assert 0 < entry["min_us"] <= entry["p50_us"] <= entry["p99_us"]


def test_shared_memory_section_compares_ours_with_zeromq_and_a_memcpy(report):
    data = report[1]
    shared = data["shared_memory"]
    # every message of ours through shared memory (the warm-up probes too), none of the ZeroMQ variant's
    assert shared["shared_count"] >= shared["messages_sent"] == 20 + 4
    assert shared["ours_zeromq"]["intact"] and shared["ours_zeromq"]["receiver"]["timed"] == 20
    assert shared["memcpy"]["intact"] and shared["memcpy"]["mb_per_s"] > 0
    assert shared["throughput_ratio"] == data["throughput_ratio"]
    assert shared["memcpy_ratio"] == pytest.approx(data["ours_throughput_mb_per_s"] / shared["memcpy"]["mb_per_s"])
    assert shared["zeromq_throughput_ratio"] == pytest.approx(shared["ours_zeromq"]["mb_per_s"]
                                                              / data["raw_throughput_mb_per_s"])
    ours, raw = data["throughput"]["ours"], data["throughput"]["raw"]
    assert ours["cpu_us_per_message"] == pytest.approx(ours["sender_cpu_us_per_message"]
                                                       + ours["receiver"]["cpu_us_per_message"])
    assert shared["cpu_throughput_ratio"] == pytest.approx(ours["cpu_mb_per_s"] / raw["cpu_mb_per_s"])
    goals = shared["goals"]
    assert (goals["throughput_ratio_min"], goals["memcpy_ratio_min"]) == (3.0, 0.5)
    assert goals["memcpy_met"] == (shared["memcpy_ratio"] >= 0.5)


def test_the_loaned_writer_fills_segments_and_its_fills_are_left_out_of_its_figures(report):
    data = report[1]
    shared, raw = data["shared_memory"], data["throughput"]["raw"]
    loaned = shared["loaned"]
    assert loaned["intact"] and loaned["receiver"]["timed"] == 20 and loaned["receiver"]["full_checks"] >= 4
    assert loaned["shared_count"] >= 24  # every message through a loaned segment
    # the fills are timed apart and taken off: the net rate is at least the gross one, the CPU at most
    assert loaned["fill_us_per_message"] > 0 and loaned["fill_cpu_us_per_message"] >= 0
    assert loaned["mb_per_s"] >= loaned["gross"]["mb_per_s"]
    assert loaned["sender_cpu_us_per_message"] <= loaned["gross"]["sender_cpu_us_per_message"]
    writers = shared["writers"]
    assert set(writers) == {"publish", "loaned", "loaned_with_fills"}
    assert writers["publish"]["throughput_ratio"] == pytest.approx(data["throughput_ratio"])
    assert writers["loaned"]["throughput_ratio"] == pytest.approx(loaned["mb_per_s"] / raw["mb_per_s"])
    assert writers["loaned"]["memcpy_ratio"] == pytest.approx(loaned["mb_per_s"] / shared["memcpy"]["mb_per_s"])
    assert writers["loaned"]["cpu_throughput_ratio"] == pytest.approx(loaned["cpu_mb_per_s"] / raw["cpu_mb_per_s"])
    assert writers["loaned_with_fills"]["throughput_ratio"] == pytest.approx(loaned["gross"]["mb_per_s"]
                                                                            / raw["mb_per_s"])
    assert writers["loaned_with_fills"]["cpu_throughput_ratio"] <= writers["loaned"]["cpu_throughput_ratio"]
    for ratios in writers.values():
        assert ratios["goal_met"] == (ratios["throughput_ratio"] >= 3.0 and ratios["memcpy_ratio"] >= 0.5)


def test_text_report_names_both_variants_and_the_ratios(report):
    text = bench_cmd.load_transport_bench().format_report(report[1])
    assert "raw pyzmq PUB/SUB" in text and "ours (graph)" in text and "ours, loaned" in text
    assert "writer publish" in text and "writer loaned" in text
    assert f"throughput_ratio  : {report[1]['throughput_ratio']:.3f}  (goal >= 0.9; through shared memory >= 3.0" \
        in text
    assert text.endswith("messages intact: yes")


@pytest.mark.parametrize("argv, message", [
    (["--messages", "0"], "--messages must be an integer >= 1; got 0"),
    (["--round-trips", "-2"], "--round-trips must be an integer >= 1; got -2"),
])
def test_bad_options_exit_2_with_a_message(capsys, argv, message):
    assert main(["bench", "transport", "--size", "small", *argv]) == 2
    assert message in capsys.readouterr().err
