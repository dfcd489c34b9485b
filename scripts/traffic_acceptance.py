#!/usr/bin/env python3
"""Summarise scripts/traffic_acceptance.sh: one table per network, the checks of issue 15.

    traffic_acceptance.py OUT

SPEED_RATIO (default 0.85) and SSM_POINTS (default 10) set the checks' bounds: the policy's mean
ego speed at least SPEED_RATIO of SUMO's drivers', its share of egos in an SSM conflict at most
theirs plus SSM_POINTS percentage points (issue 62's zoo asks 0.9 and 5).

Reads OUT/<network>/<routes stem>_seed<S>_{ego,game,mainline30}/cosim.json (and the tripinfo
files next to it) and prints Markdown.
"""
import json
import os
import re
import sys
import xml.etree.ElementTree as ET
from pathlib import Path
from statistics import mean


def run_metrics(run):
    egos = run["egos"]
    finished = [e for e in egos if e["finished"]]
    conflicts = [e for e in finished if e["ssm_min_ttc"] is not None or e["ssm_max_drac"] is not None]
    return {
        "finished": len(finished),
        "controlled_collisions": sum(1 for c in run["collisions"] if c["controlled"]),
        "failures": run["summary"]["failures"],
        "speed": run["summary"]["mean_speed"],
        "ssm": len(conflicts) / len(finished) if finished else 0.0,
    }


def all_time_loss(folder, controller):
    """Mean time loss of every vehicle that finished its trip (tripinfo)."""
    path = folder / f"tripinfo-{controller}.xml"
    losses = [float(t.get("timeLoss")) for t in ET.parse(path).getroot().iter("tripinfo")
              if float(t.get("arrival", "-1")) >= 0]
    return mean(losses), len(losses)


def main():
    out = Path(sys.argv[1])
    speed_ratio = float(os.environ.get("SPEED_RATIO", "0.85"))
    ssm_points = float(os.environ.get("SSM_POINTS", "10"))
    print("# The traffic policy in SUMO against SUMO's drivers\n")
    failed = []
    shields = set()
    for net in sorted(p for p in out.iterdir() if p.is_dir()):
        rows = {}
        beyond = []
        for folder in sorted(net.iterdir()):
            m = re.match(r".*_d([0-9.]+)(?:_m[0-9.]+)?_s\d+_seed(\d+)_(ego|game|mainline30)$", folder.name)
            if not m or not (folder / "cosim.json").is_file():
                continue
            scale, seed, mode = float(m.group(1)), int(m.group(2)), m.group(3)
            runs = {r["controller"]: r for r in json.loads((folder / "cosim.json").read_text())}
            sh = runs["mpg"]["shields"]
            shields.add((sh["merge_gate"], sh["speed_mode"], sh["lane_change_mode"],
                         sh.get("player_lane_change_mode")))
            if mode == "mainline30":
                beyond.append((scale, seed, all_time_loss(folder, "mpg"), all_time_loss(folder, "sumo")))
                continue
            row = rows.setdefault((scale, seed), {})
            if mode == "ego":
                row["sumo"] = run_metrics(runs["sumo"])
                row["ego"] = run_metrics(runs["mpg"])
            else:
                row["game"] = run_metrics(runs["mpg"])
        if not rows and not beyond:
            continue  # not a network's runs (the zoo's networks themselves, say)
        print(f"## {net.name}\n")
        print("| demand | SUMO seed | deployment | finished egos (SUMO's) | controlled collisions | failures "
              "| mean ego speed, m/s (ratio to SUMO's) | egos with an SSM conflict (SUMO's) | holds |")
        print("|---|---|---|---|---|---|---|---|---|")
        for (scale, seed), row in sorted(rows.items()):
            s = row.get("sumo")
            for mode in ("ego", "game"):
                r = row.get(mode)
                if r is None or s is None:
                    continue
                ratio = r["speed"] / s["speed"] if s["speed"] > 0 else float("nan")
                checks = {
                    "no collision": r["controlled_collisions"] == 0,
                    "no failure": r["failures"] == 0,
                    "finished >= 98%": r["finished"] >= 0.98 * s["finished"],
                    f"speed >= {speed_ratio:g}": ratio >= speed_ratio,
                    f"SSM <= +{ssm_points:g} points": r["ssm"] <= s["ssm"] + ssm_points / 100,
                }
                bad = [k for k, ok in checks.items() if not ok]
                if bad:
                    failed.append(f"{net.name} d{scale} seed {seed} {mode}: {', '.join(bad)}")
                print(f"| {scale} | {seed} | {'ego only' if mode == 'ego' else 'the game'} "
                      f"| {r['finished']} ({s['finished']}) | {r['controlled_collisions']} | {r['failures']} "
                      f"| {r['speed']:.2f} ({ratio:.2f}) | {100 * r['ssm']:.0f}% ({100 * s['ssm']:.0f}%) "
                      f"| {'yes' if not bad else 'no: ' + ', '.join(bad)} |")
        if beyond:
            print("\nDemand 1.2, 30% of the freeway vehicles controllable and playing the game: mean time loss "
                  "of every vehicle that finished (tripinfo), s\n")
            print("| SUMO seed | the game | SUMO's drivers alone | at most SUMO's |")
            print("|---|---|---|---|")
            for scale, seed, (mpg, n_mpg), (sumo, n_sumo) in sorted(beyond):
                print(f"| {seed} | {mpg:.2f} ({n_mpg} vehicles) | {sumo:.2f} ({n_sumo}) | {'yes' if mpg <= sumo else 'no'} |")
        print()
    print("## Shields of the mpg runs\n")
    for gate, speed, lane, player_lane in sorted(shields, key=str):
        players = "" if player_lane is None else f" (target-lane players {player_lane})"
        print(f"- merge gate {'on' if gate else 'off'}, SUMO speed mode {speed}, lane-change mode {lane}{players}")
    print("\n## Verdict\n")
    if failed:
        print(f"{len(failed)} deployments miss the acceptance:\n")
        for f in failed:
            print(f"- {f}")
    else:
        print("Every deployment meets the acceptance.")


if __name__ == "__main__":
    main()
