"""The scan monitor's per-scan line: ok within the bounds, UNTRUSTED with the reason, FAILED and LOST as before."""
from __future__ import annotations

from dptpu.nodes.scan_monitor.node import ScanMonitorNode


def _record(**changes) -> dict:
    record = {"sequence_id": 3, "scene": "random-2", "outcome": "ok", "valid_points": 17300, "wrong_share": 0.0,
              "completeness": 0.976, "order_accuracy": 1.0, "depth_rms_mm": 0.84, "depth_rms_right_order_mm": 0.84,
              "latency_ms": 5.2}
    record.update(changes)
    return record


def test_a_trusted_scan_says_ok_with_its_precision_and_completeness():
    assert ScanMonitorNode._line(_record()) == (
        "scan 3 random-2: ok, 17,300 points, 0.000 % wrong, 97.6 % complete, fringe orders 100.00 %, depth RMS "
        "0.840 mm (0.840 mm where the order is right), latency 5 ms")


def test_an_untrusted_scan_names_the_figure_out_of_bounds():
    line = ScanMonitorNode._line(_record(outcome="untrusted", wrong_share=0.0135,
                                         reason="1.35 % of the points wrong (> 0.10 %)"))
    assert line.startswith("scan 3 random-2: UNTRUSTED (1.35 % of the points wrong (> 0.10 %)), 17,300 points, "
                           "1.350 % wrong, 97.6 % complete")


def test_failed_and_lost_scans_keep_their_lines():
    assert ScanMonitorNode._line({"sequence_id": 9, "scene": "", "outcome": "lost", "reason": "no cloud within 3 s"}) \
        == "scan 9: LOST: no cloud within 3 s"


def test_the_summary_file_is_json_with_a_record_a_line_and_leaves_no_garbage_cycles():
    import gc
    import json

    from dptpu.nodes.scan_monitor.node import summary_json

    records = [_record(sequence_id=i, node_durations_s={"/phase": 0.01}) for i in range(200)]
    totals = {"scans": 200, "ok": 200, "latency_ms_p50": 5.2}
    gc.collect()
    gc.disable()  # no automatic collection in between: each write's cycles stay to be counted
    try:
        for _ in range(20):
            text = summary_json(totals, records)
    finally:
        gc.enable()
    assert gc.collect() == 0  # json.dumps(indent=1): about 30 unreachable objects a write
    assert json.loads(text) == {"totals": totals, "scans": records}
    assert len(text.splitlines()) == 203 and json.loads(text.splitlines()[2].rstrip(",")) == records[0]
