#!/usr/bin/env python3
"""Writes the docs' current results from the tools, never by hand.

    scripts/results.py paper          Tables II and III, the paper's claims and the specific
                                      scenarios per policy seed (mpgdrive report, scenario)
    scripts/results.py traffic        the internal traffic study of policies/traffic, per seed
                                      (mpgdrive eval --config configs/traffic.toml)
    scripts/results.py grid DIR       the SUMO grid on the bundled networks, from
                                      scripts/traffic_acceptance.sh DIR's acceptance.md
    scripts/results.py zoo DIR        the merge zoo, from scripts/zoo_acceptance.sh DIR
    scripts/results.py zoo-shielded DIR  the merge zoo with SUMO's safe speed as a shield, from
                                      SPEED_MODE=25 scripts/zoo_acceptance.sh DIR
    scripts/results.py study DIR      the penetration study, from `mpgdrive study --out DIR`
                                      (its table, and its plot as docs/results/study.png)
    scripts/results.py study-zoo DIR  the penetration study on a zoo network, from
                                      scripts/zoo_study.sh NAME DIR (docs/results/study-zoo.md)
    scripts/results.py study-junction DIR  the same on a zoo junction merge
                                      (docs/results/study-junction.md)

Each writes docs/results/KIND.md, then docs/results/summary.md from all of them and README's
results block. Every file's first line records the policy files and configuration it
describes with their SHA-256 (`sha256sum FILES | sha256sum`, files sorted by path):
tests/docs.rs fails when a shipped policy changes without the results being regenerated.
MPGDRIVE names the binary (default target/release/mpgdrive). Python 3 standard library only.
"""
import glob
import hashlib
import json
import os
import re
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RESULTS = os.path.join(ROOT, "docs", "results")
BIN = os.environ.get("MPGDRIVE", os.path.join(ROOT, "target", "release", "mpgdrive"))
PAPER_INPUTS = ["configs/paper.toml", "policies/mpg/*.json", "policies/mpg/*.safetensors",
                "policies/sarl/*.json", "policies/sarl/*.safetensors"]
TRAFFIC_INPUTS = ["configs/traffic.toml", "policies/traffic/*/*.json",
                  "policies/traffic/*/*.safetensors"]
INPUTS = {"paper": PAPER_INPUTS, "traffic": TRAFFIC_INPUTS, "grid": TRAFFIC_INPUTS,
          "zoo": TRAFFIC_INPUTS, "zoo-shielded": TRAFFIC_INPUTS, "study": TRAFFIC_INPUTS,
          "study-zoo": TRAFFIC_INPUTS, "study-junction": TRAFFIC_INPUTS}
FOLDERS = ("grid", "zoo", "zoo-shielded", "study", "study-zoo", "study-junction")
ZOO_STUDIES = ("study-zoo", "study-junction")
TITLES = {"paper": "The paper's study (Tables II and III, claims, scenarios)",
          "traffic": "The traffic policies in their own world",
          "grid": "The traffic policies in SUMO on the bundled networks",
          "zoo": "The traffic policies in SUMO on the merge zoo",
          "zoo-shielded": "The traffic policies in SUMO on the merge zoo, SUMO's safe speed as a shield",
          "study": "The game against SUMO's drivers, by share of controllable vehicles",
          "study-zoo": "The game against SUMO's drivers on a zoo network, by share of controllable vehicles",
          "study-junction": "The game against SUMO's drivers on a zoo junction merge, by share of controllable vehicles"}
README_BEGIN = "<!-- results: docs/results/summary.md -->"
README_END = "<!-- /results -->"


def inputs_hash(patterns):
    """SHA-256 of `sha256sum FILES` over the sorted files the patterns match."""
    files = sorted({f for p in patterns for f in glob.glob(p, root_dir=ROOT)})
    if not files:
        sys.exit(f"results: no file matches {patterns}")
    lines = ""
    for f in files:
        with open(os.path.join(ROOT, f), "rb") as h:
            lines += f"{hashlib.sha256(h.read()).hexdigest()}  {f}\n"
    return hashlib.sha256(lines.encode()).hexdigest()


def header(kind, command):
    patterns = INPUTS[kind]
    return (f"<!-- written by scripts/results.py {kind}; inputs: {' '.join(patterns)}; "
            f"sha256: {inputs_hash(patterns)} -->\n# {TITLES[kind]}\n\n"
            f"Written by `{command}`; do not edit.\n\n")


def write(name, text):
    """Writes docs/results/NAME atomically (a temporary file, then a rename)."""
    os.makedirs(RESULTS, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=RESULTS, prefix=f".{name}.")
    with os.fdopen(fd, "w") as h:
        h.write(text)
    os.replace(tmp, os.path.join(RESULTS, name))


def run(*args):
    out = subprocess.run([BIN, *args], cwd=ROOT, capture_output=True, text=True)
    if out.returncode != 0:
        sys.exit(f"results: `mpgdrive {' '.join(args)}` failed:\n{out.stderr}")
    return out.stdout


SCENARIOS = {1: (4, 5), 2: (5, 6)}


def paper():
    with tempfile.TemporaryDirectory() as tmp:
        run("report", "--out", os.path.join(tmp, "report"))
        parts = [open(os.path.join(tmp, "report", f)).read().strip()
                 for f in ("table2.md", "table3.md", "claims.md")]
        seeds = sorted(int(m.group(1)) for f in glob.glob("policies/mpg/seed*.json", root_dir=ROOT)
                       if (m := re.search(r"seed(\d+)\.json$", f)))
        rows = []
        for preset, (a, b) in SCENARIOS.items():
            cells = []
            for s in seeds:
                out = os.path.join(tmp, f"s{preset}_{s}")
                run("scenario", "--config", "configs/paper.toml", "--preset", str(preset),
                    "--policy", "policies/mpg", "--policy-seed", str(s), "--out", out)
                o = json.load(open(os.path.join(out, f"preset{preset}.json")))
                front, back = o["merged_between"] or (None, None)
                where = ("collision" if o["collision"] else
                         f"behind {front}" if back in (0, None) else f"{front}-{back}")
                cells.append(where)
            rows.append(f"| {preset} (paper: between {a} and {b}) | " + " | ".join(cells) + " |")
    scenarios = ("Whom the ego merges between in the paper's specific scenarios "
                 "(`mpgdrive scenario --preset K --policy-seed S`):\n\n"
                 "| scenario | " + " | ".join(f"seed {s}" for s in seeds) + " |\n"
                 "|---|" + "---|" * len(seeds) + "\n" + "\n".join(rows) + "\n")
    write("paper.md", header("paper", "scripts/results.py paper") + "\n\n".join(parts)
          + "\n\n" + scenarios)


def traffic():
    rows = []
    for mode in ("mpg", "sarl"):
        seeds = sorted(int(m.group(1)) for f in glob.glob(f"policies/traffic/{mode}/seed*.json",
                                                            root_dir=ROOT)
                       if (m := re.search(r"seed(\d+)\.json$", f)))
        for s in seeds:
            cols = json.loads(run("eval", "--config", "configs/traffic.toml", "--policy",
                                  f"policies/traffic/{mode}/seed{s}", "--json"))["columns"]
            by = {c["surroundings"]: c for c in cols}
            h, m = by["HumanOnly"], by["Mixed"]
            rows.append((mode, s, h, m))
    lines = ["Every controlled vehicle of 500 merge-traffic test episodes per seed, the policy "
             "alone (the entry rule on, no merge gate): human-only surroundings (the ego "
             "controlled, every other vehicle a human driver) and mixed ones (every non-human "
             "vehicle on the policy). Failures: a controlled ramp vehicle that started where the "
             "paper's ego does (40-120 m before x_c) still on the ramp at the horizon.\n",
             "| policy | seed | collisions, human-only | failures, human-only | speed, human-only "
             "(m/s) | collisions, mixed | failures, mixed | speed, mixed (m/s) |",
             "|---|---|---|---|---|---|---|---|"]
    for mode, s, h, m in rows:
        lines.append(f"| {mode} | {s} | {h['collisions']:g}/500 | {h['failures']:g}/500 | "
                     f"{h['speed']:.2f} | {m['collisions']:g}/500 | {m['failures']:g}/500 | "
                     f"{m['speed']:.2f} |")
    lines.append("\n```sh\n./target/release/mpgdrive eval --config configs/traffic.toml "
                 "--policy policies/traffic/mpg/seed0\n```\n")
    write("traffic.md", header("traffic", "scripts/results.py traffic") + "\n".join(lines))


def acceptance(kind, folder):
    path = os.path.join(folder, "acceptance.md")
    if not os.path.isfile(path):
        sys.exit(f"results: {path} does not exist (run scripts/"
                 f"{'traffic' if kind == 'grid' else 'zoo'}_acceptance.sh {folder} first)")
    body = open(path).read()
    shielded = re.search(r"^- merge gate .*SUMO speed mode 0,", body, re.M) is None
    if shielded != (kind == "zoo-shielded"):
        sys.exit(f"results: {path} was run with SUMO's safe speed {'on' if shielded else 'off'}: "
                 f"it is `scripts/results.py {'zoo-shielded' if shielded else 'zoo'} DIR`'s")
    body = re.sub(r"^# .*\n+", "", body, count=1)
    script = "traffic_acceptance.sh" if kind == "grid" else "zoo_acceptance.sh"
    env = "SPEED_MODE=25 " if shielded else ""
    write(f"{kind}.md", header(kind, f"{env}scripts/{script} DIR && scripts/results.py {kind} DIR")
          + body)


def study(kind, folder):
    """docs/results/KIND.md and KIND.png from a `mpgdrive study` output folder (study), or from
    scripts/zoo_study.sh's output folder (study-zoo, study-junction: its study/ and the network's
    name)."""
    network = ""
    if kind in ZOO_STUDIES:
        zoo = os.path.join(folder, "zoo.txt")
        if not os.path.isfile(zoo):
            sys.exit(f"results: {zoo} does not exist (run `scripts/zoo_study.sh NAME {folder}` first)")
        name, build = open(zoo).read().strip().split(": ", 1)
        network = (f"Network: the zoo's `{name}`, built by `mpgdrive net build {build}` "
                   "(scripts/zoo_nets.sh).\n\n")
        command = f"scripts/zoo_study.sh {name} DIR ... && scripts/results.py {kind} DIR"
        folder = os.path.join(folder, "study")
    else:
        command = "mpgdrive study --out DIR && scripts/results.py study DIR"
    path = os.path.join(folder, "study.md")
    if not os.path.isfile(path):
        sys.exit(f"results: {path} does not exist (run `mpgdrive study --out {folder}` first)")
    write(f"{kind}.md", header(kind, command) + network + open(path).read()
          + f"\n![The penetration study]({kind}.png)\n")
    fd, tmp = tempfile.mkstemp(dir=RESULTS, prefix=f".{kind}.png.")
    with os.fdopen(fd, "wb") as h, open(os.path.join(folder, "study.png"), "rb") as png:
        h.write(png.read())
    os.replace(tmp, os.path.join(RESULTS, f"{kind}.png"))


def study_rows(kind):
    """The summary's lines from docs/results/KIND.md (a study): the time-loss ratio by share,
    the share from which the game beats SUMO's drivers, the merge's own cost and the part of
    it the game saves, and the merge's capacity when the study swept it."""
    path = os.path.join(RESULTS, f"{kind}.md")
    if not os.path.isfile(path):
        return []
    text = open(path).read()
    rows = [line.split("|")[1:-1] for line in text.split("\n\n| controllable share", 2)[1].splitlines()
            if re.match(r"\| \d+% \|", line)] if "\n\n| controllable share" in text else []
    ratios = [(c[0].strip(), c[-1].strip()) for c in rows if c[0].strip() != "0%"]
    net = re.search(r"`([^`]*)\.sumocfg`, demand ([\d.]+)", text)
    zoo = re.search(r"^Network: the zoo's `([^`]*)`", text, re.M)
    seeds = re.search(r"seeds ([\d, ]+), ([\d.]+) s runs", text)
    name = zoo.group(1) if zoo else os.path.basename(os.path.dirname(net.group(1))) if net else "?"
    setting = (f"{name}, demand {net.group(2)}, seeds {seeds.group(1)}, {seeds.group(2)} s"
               if net and seeds else "?")
    verdict = re.search(r"^(The game('s)? .*)$", text, re.M)
    capacity = re.search(r"^(The merge (breaks|does not break) .*)$", text, re.M)
    cost = re.search(r"lose ([\d.]+) ± [\d.]+ s per vehicle: ([\d.]+) times SUMO's drivers' "
                     r"([\d.]+) s", text)
    saved = re.findall(r"^\| (\d+%) \| (-?[\d.]+%|-) \|$", text.split("## The merge's own cost")[-1], re.M)
    out = [
        f"| Penetration study ({setting}): time loss of every vehicle, the game / SUMO's drivers "
        f"alone, at {' / '.join(r[0] for r in ratios)} controllable vehicles "
        f"| {' / '.join(r[1] for r in ratios)} | `{kind}.md` |",
        f"| {name}: {verdict.group(1) if verdict else '?'} | | `{kind}.md` |",
    ]
    if cost and saved:
        out.append(f"| {name}: each stream alone (the merge costing nothing), time loss / SUMO's "
                   f"drivers' with both; the part of the merge's cost the game saves at "
                   f"{' / '.join(s[0] for s in saved)} | {cost.group(2)}; {' / '.join(s[1] for s in saved)} "
                   f"| `{kind}.md` |")
    if capacity:
        out.append(f"| Capacity of the merge, SUMO's drivers alone ({setting.split(', demand')[0]}): "
                   f"{capacity.group(1)} | | `{kind}.md` |")
    return out


def deployments(kind):
    """(held, total, controlled collisions) over the deployment rows of a grid or zoo results
    file, or None."""
    path = os.path.join(RESULTS, f"{kind}.md")
    if not os.path.isfile(path):
        return None
    rows = [line.split("|") for line in open(path)
            if re.match(r"\| [\d.]+ \| \d+ \| (ego only|the game) \|", line)]
    held = sum(r[-2].strip() == "yes" for r in rows)
    return held, len(rows), sum(int(r[5]) for r in rows)


def summary():
    """docs/results/summary.md from the other files, and README's block."""
    def cell(pattern, text):
        m = re.search(pattern, text, re.M)
        return m.group(1).strip() if m else "?"
    rows = [row for kind in ("study",) + ZOO_STUDIES for row in study_rows(kind)]
    paper_md = open(os.path.join(RESULTS, "paper.md")).read()
    t2 = paper_md.split("Statistical results: Single-agent RL")[0]
    ne_idm = cell(r"^\| Collision rate \| (.*?) \|$", t2).replace("/500", "").replace(" | ", " / ")
    rows.append(f"| Table II: MARL ego collisions per 500, under NE / IDM / constant-speed players "
                f"| {ne_idm} | `paper.md` |")
    claims = re.search(r"(\d+) of (\d+) claims hold", paper_md)
    rows.append(f"| The paper's claims about Tables II and III that hold | {claims.group(1)} of "
                f"{claims.group(2)} | `paper.md` |")
    for preset, (a, b) in SCENARIOS.items():
        line = cell(rf"^(\| {preset} \(paper.*)$", paper_md)
        cells = [c.strip() for c in line.strip("|").split("|")[1:]]
        rows.append(f"| Scenario {preset}: policy seeds whose ego merges between {a} and {b}, as "
                    f"in the paper | {sum(c == f'{a}-{b}' for c in cells)} of {len(cells)} | "
                    "`paper.md` |")
        part = paper_md.split(f"Scenario {preset}: ", 1)[-1]
        shares = re.findall(r"^\| \d+ \| \d+ \((\d+)%\) \|", part.split("seeds merge where")[0], re.M)
        n = re.search(r"(\d+) states drawn", part)
        rows.append(f"| Scenario {preset}, {n.group(1) if n else '?'} states drawn from its description: "
                    f"share with the paper's outcome by seed | {' / '.join(s + '%' for s in shares)} "
                    "| `paper.md` |")
    traffic_md = os.path.join(RESULTS, "traffic.md")
    if os.path.isfile(traffic_md):
        mpg = [line.split("|")[1:-1] for line in open(traffic_md) if line.startswith("| mpg |")]
        per_seed = lambda k: " / ".join(c[k].strip().split("/")[0] for c in mpg)
        rows.append("| Traffic policy alone in its world, collisions per 500 by seed, "
                    f"human-only surroundings | {per_seed(2)} | `traffic.md` |")
        rows.append("| the same, mixed surroundings (every non-human vehicle on the policy) "
                    f"| {per_seed(5)} | `traffic.md` |")
    for kind, what in (("grid", "SUMO, bundled networks"), ("zoo", "SUMO, merge zoo"),
                       ("zoo-shielded", "SUMO, merge zoo")):
        path = os.path.join(RESULTS, f"{kind}.md")
        if os.path.isfile(path):
            speed_mode = cell(r"^- merge gate .*SUMO speed mode (\d+)", open(path).read())
            what += (" (the policy alone, cosim's default)" if speed_mode == "0"
                     else " (shielded: SUMO's safe speed on)")
        held = deployments(kind)
        if held:
            rows.append(f"| {what}: deployments meeting every check against SUMO's drivers "
                        f"| {held[0]} of {held[1]} | `{kind}.md` |")
            rows.append(f"| {what}: collisions involving a vehicle the policy drives, all "
                        f"{held[1]} runs | {held[2]} | `{kind}.md` |")
    table = ("| Result | Figure | Details |\n|---|---|---|\n" + "\n".join(rows) + "\n")
    write("summary.md", f"<!-- written by scripts/results.py from docs/results/*.md; inputs: "
          f"{' '.join(sorted(set(PAPER_INPUTS + TRAFFIC_INPUTS)))}; sha256: "
          f"{inputs_hash(sorted(set(PAPER_INPUTS + TRAFFIC_INPUTS)))} -->\n{table}")
    readme = os.path.join(ROOT, "README.md")
    text = open(readme).read()
    if README_BEGIN in text and README_END in text:
        before, rest = text.split(README_BEGIN, 1)
        _, after = rest.split(README_END, 1)
        fd, tmp = tempfile.mkstemp(dir=ROOT, prefix=".README.")
        with os.fdopen(fd, "w") as h:
            h.write(before + README_BEGIN + "\n" + table + README_END + after)
        os.replace(tmp, readme)


def main():
    args = sys.argv[1:]
    if not args or args[0] not in INPUTS or (args[0] in FOLDERS) != (len(args) == 2):
        sys.exit(__doc__)
    kind = args[0]
    if kind == "paper":
        paper()
    elif kind == "traffic":
        traffic()
    elif kind in ("study",) + ZOO_STUDIES:
        study(kind, args[1])
    else:
        acceptance(kind, args[1])
    summary()


if __name__ == "__main__":
    main()
