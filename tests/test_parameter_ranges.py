"""A component's declared range, as a user sees it: ``ros2 param describe`` and ``set``.

The JPEG compressor declares ``jpeg_quality`` with ``range=JPEG_QUALITY`` once; here it runs
as ``ros2 run`` starts it, and the ``ros2`` command (a separate process, as a user types it)
reads the range from its descriptor and is refused a value outside it, with the reason.
"""

from __future__ import annotations

from pathlib import Path

from debug_probes import JPEG_QUALITY
from efficient_comm.testing import isolated_domain_id

from ._cli import ros2, ros2_path, running


def test_ros2_param_describe_shows_the_range_and_set_is_refused_outside_it(
        tmp_path: Path) -> None:
    domain = isolated_domain_id()
    low, high = JPEG_QUALITY
    with running([ros2_path(), "run", "debug_probes", "jpeg_compressor"], domain_id=domain,
                 log=tmp_path / "compressor.log"):
        described = ros2("param", "describe", "/jpeg_compressor", "jpeg_quality",
                         domain_id=domain)
        assert described.returncode == 0, described.stderr
        assert (f"  Constraints:\n    Min value: {low}\n    Max value: {high}\n"
                in described.stdout), described.stdout
        refused = ros2("param", "set", "/jpeg_compressor", "jpeg_quality", str(high + 1),
                       domain_id=domain)
        assert refused.returncode == 1 and "Traceback" not in refused.stderr
        assert "out of range" in refused.stderr + refused.stdout, refused
        accepted = ros2("param", "set", "/jpeg_compressor", "jpeg_quality", str(high),
                        domain_id=domain)
        assert accepted.stdout == "Set parameter successful\n", accepted
