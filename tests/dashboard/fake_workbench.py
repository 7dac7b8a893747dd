"""A stand-in for ``workbench run`` in the Run-page tests: records like the runner, without the simulator.

``fake_workbench.py run PROC --unit U --rig sim --out DIR [--seed N]`` writes ``DIR/session.json``
with 3 planned static steps, appends one step (and ``parts/step_NNNNN.parquet``) every
``STEP_S`` seconds, then ``DIR/result.json``; procedure ``fails`` stops after the first step
with an error message and exit code 2, as the real CLI does for a WorkbenchError; procedure
``slow`` takes 3 s per step (to be stopped).
"""

import json
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

STEP_S = {"slow": 3.0}  # s of wall time per fake step, by procedure name (default 0.2 s)
DWELL_S = 10.0  # s of rig time per step, 10 Hz


def main(argv: list[str]) -> int:
    proc, out = argv[1], Path(argv[argv.index("--out") + 1])
    out.mkdir(parents=True)
    planned = [{"kind": "static", "duration_s": DWELL_S} for _ in range(3)]
    manifest = {"format": "workbench-session/1", "procedure": proc, "planned": planned, "steps": []}
    for i in range(3):
        time.sleep(STEP_S.get(proc, 0.2))
        t = i * DWELL_S + np.arange(int(DWELL_S * 10)) / 10
        df = pd.DataFrame({"t": t, "step": i, **{c: np.full(t.size, 0.1 * k) for k, c in enumerate(
            ["gx", "gy", "gz", "ax", "ay", "az"])}})
        (out / "parts").mkdir(exist_ok=True)
        df.to_parquet(out / "parts" / f"step_{i:05d}.parquet", index=False)
        manifest["steps"].append({"index": i, "kind": "static", "t_start": t[0], "t_end": t[0] + DWELL_S})
        (out / "session.json").write_text(json.dumps(manifest))
        if proc == "fails":
            print(f"error: {out}: step 0 (static): gyro norm 0.8 rad/s is not static", file=sys.stderr)
            return 2
    (out / "result.json").write_text(json.dumps({"procedure": proc, "warnings": ["fake warning"],
                                                 "calibration_id": None}))
    print(f"{proc}: done")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
