"""The `key = value` lines the project's programs print (hdjoint-host's and
hd_soak's summaries, the VM runner's) and its build step writes
(build_info.txt): parsed once, here."""
from __future__ import annotations


def parse(text: str) -> dict[str, str]:
    """Every line with " = " as key -> value (split at the first one); other
    lines are ignored."""
    return dict(line.split(" = ", 1) for line in text.splitlines() if " = " in line)
