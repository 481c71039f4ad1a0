"""rig_expected.cfg is what `hdsense analyze` identifies for the rig's joint
(tests/reliability/rig_identify.py), and within a few per cent of the
simulated joint's constants (the identification works; the rig never
reads those constants)."""
from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent


def test_the_rig_model_is_the_tools_identification():
    r = subprocess.run([sys.executable, str(HERE / "rig_identify.py"), "--check"],
                       capture_output=True, text=True, timeout=280)
    assert r.returncode == 0, r.stderr


def value(text: str, key: str) -> float:
    return float(re.search(rf"^{key}\s*=\s*(\S+)", text, re.M).group(1))


def test_the_identified_model_is_close_to_the_joint():
    model = (HERE / "rig_expected.cfg").read_text()
    joint = (HERE / "rig_joint.ini").read_text()
    for cfg_key, ini_key in (("inertia_kgm2", "load_inertia_kgm2"),
                             ("viscous_nm_s_rad", "viscous_nm_s_rad"), ("coulomb_nm", "coulomb_nm")):
        got, true = value(model, cfg_key), value(joint, ini_key)
        assert abs(got - true) <= 0.05 * true, (cfg_key, got, true)
