"""Print one closing line with the totals of several pytest JUnit XML reports.

The host run and the UML (vcan) run are two pytest sessions; this line is the
sum of both, so the last thing a reader (or CI) sees is the whole result. JUnit
XML has no "expected failure": pytest writes an xfail as ``<skipped
type="pytest.xfail">``; it is counted as xfailed here, as pytest's own summary does.
"""

import sys
import xml.etree.ElementTree as ET
from collections import Counter

XFAIL_TYPE = "pytest.xfail"


def outcome(case: ET.Element) -> str:
    """passed, failed, skipped or xfailed, for one ``<testcase>``."""
    if case.find("failure") is not None or case.find("error") is not None:
        return "failed"
    skipped = case.find("skipped")
    if skipped is not None:
        return "xfailed" if skipped.get("type") == XFAIL_TYPE else "skipped"
    return "passed"


def main(paths: list[str]) -> int:
    totals: Counter[str] = Counter()
    for path in paths:
        try:
            root = ET.parse(path).getroot()
        except (OSError, ET.ParseError) as exc:
            print(f"summary: no report {path} ({exc})")
            totals["failed"] += 1
            continue
        totals.update(outcome(case) for case in root.iter("testcase"))
    line = ", ".join(f"{totals[what]} {what}" for what in ("passed", "failed", "skipped"))
    if totals["xfailed"]:
        line += f", {totals['xfailed']} xfailed"
    print(line)
    return 0 if totals["failed"] == 0 else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
