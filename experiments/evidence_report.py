"""Markdown tables of the evidence results (ablations, CEC2006, paper tables) from their JSON.

    python experiments/evidence_report.py --out docs/evidence.md
    python experiments/evidence_report.py --results /tmp/quick   # tables of another folder

A table appears only for a result JSON that exists.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results"


def load(name: str) -> list[dict] | None:
    p = RESULTS / name
    return json.loads(p.read_text())["rows"] if p.exists() else None


def meta(name: str) -> dict:
    p = RESULTS / name
    return json.loads(p.read_text()).get("meta", {}) if p.exists() else {}


def num(v, fmt: str = ".2f") -> str:
    return "-" if v is None else format(v, fmt)


def p_fmt(v) -> str:
    return "-" if v is None else (f"{v:.1e}" if v < 1e-3 else f"{v:.3f}")


def wins(rows: list[dict], r: dict, key: str, match: tuple[str, ...]) -> str:
    """'w/l': seeds where the cell is better / worse than its reference (None = worst)."""
    if r.get("reference") is None:
        return "-"
    ref = next(x for x in rows if x["cell"] == r["reference"]
               and all(x[k] == r[k] for k in match))
    inf = float("inf")
    a = [inf if v is None else v for v in r[key]]
    b = [inf if v is None else v for v in ref[key]]
    w = sum(x < y for x, y in zip(a, b, strict=True))
    worse = sum(x > y for x, y in zip(a, b, strict=True))
    return f"{w}/{worse}"


TSP_KEYS = ("instances", "modes", "tours_none", "tours_2opt", "seeds")
CON_KEYS = ("problems", "budget", "seeds")


def run_note(name: str, keys: tuple[str, ...] = ()) -> None:
    """One line on how a JSON was made: device, cores, note; a merged file's parts."""
    m = meta(name)
    if not m:
        return
    parts = m.get("parts") or [m]
    bits = []
    for q in parts:
        what = ", ".join(f"{k} {q[k]}" for k in keys if k in q)
        bits.append(f"{what} on {q.get('device', '?')}"
                    + (f" ({q['cpu_cores']} cores)" if "cpu_cores" in q else ""))
    print(f"\n_`{name}`: " + "; ".join(bits)
          + (f". Note: {m['note']}" if m.get("note") else "") + "._")


def tsp() -> None:
    rows = load("ablation_tsp.json")
    if not rows:
        return
    print("\n## TSP ablation (`experiments/ablation.py tsp`)")
    run_note("ablation_tsp.json", TSP_KEYS)
    sig = [r for r in rows if r.get("p_holm") is not None and r["p_holm"] < 0.05]
    print("\nCells different from their reference (paired Wilcoxon on the final lengths, "
          "Holm-adjusted within each instance x mode, p < 0.05):\n")
    for r in sig:
        print(f"- {r['instance']}, {'2-opt' if r['local_search'] != 'none' else 'no LS'}, "
              f"**{r['cell']}** vs {r['reference']}: gap {r['gap_mean']:.2f} % "
              f"[{r['gap_ci_low']:.2f}, {r['gap_ci_high']:.2f}] "
              f"({'worse' if r['delta_gap_mean'] > 0 else 'better'}, "
              f"{r['delta_gap_mean']:+.2f} points), p Holm {p_fmt(r['p_holm'])}")
    if not sig:
        print("- none")
    for inst in dict.fromkeys(r["instance"] for r in rows):
        for ls in dict.fromkeys(r["local_search"] for r in rows):
            sel = [r for r in rows if r["instance"] == inst and r["local_search"] == ls]
            if not sel:
                continue
            r0 = sel[0]
            print(f"\n### {inst}, {'2-opt' if ls != 'none' else 'no local search'}: "
                  f"{r0['tours']:,} tours ({r0['ants']} ants x {r0['iterations']}), "
                  f"{r0['seeds']} seeds\n")
            print("| cell | gap % mean [95% CI] | gap % at 25% budget | opt hit | "
                  "Δ vs ref | better/worse seeds | p (Wilcoxon) | p Holm | "
                  "gap % at equal time |")
            print("|---|---|---|---|---|---|---|---|---|")
            for r in sel:
                print(f"| {r['cell']} | {r['gap_mean']:.2f} [{r['gap_ci_low']:.2f}, "
                      f"{r['gap_ci_high']:.2f}] | {r['gap_mean_at_25pct']:.2f} | "
                      f"{r['success_rate']:.2f} | {num(r.get('delta_gap_mean'), '+.2f')} | "
                      f"{wins(rows, r, 'final_lengths', ('instance', 'local_search'))} | "
                      f"{p_fmt(r.get('p_value'))} | {p_fmt(r.get('p_holm'))} | "
                      f"{r['wall_gap_mean']:.2f} |")


def constrained() -> None:
    rows = load("ablation_constrained.json")
    if not rows:
        return
    print("\n## Constrained ablation (`experiments/ablation.py constrained`)")
    run_note("ablation_constrained.json", CON_KEYS)
    for prob in dict.fromkeys(r["problem"] for r in rows):
        sel = [r for r in rows if r["problem"] == prob]
        print(f"\n### {prob} derivative-free, {sel[0]['budget']:,} evaluations, "
              f"{sel[0]['seeds']} seeds\n")
        print("| cell | success | SP | error mean [95% CI] (feasible runs) | feasible | "
              "better/worse seeds | p error (Holm) | p evals (Holm) |")
        print("|---|---|---|---|---|---|---|---|")
        for r in sel:
            print(f"| {r['cell']} | {r['success_rate']:.2f} | "
                  f"{num(r['success_performance'], ',.0f')} | {r['error_mean']:.3g} "
                  f"[{r['error_ci_low']:.3g}, {r['error_ci_high']:.3g}] | "
                  f"{r['feasible_rate']:.2f} | "
                  f"{r.get('better_seeds', '-')}/{r.get('worse_seeds', '-')} | "
                  f"{p_fmt(r.get('p_error_holm'))} | "
                  f"{p_fmt(r.get('p_evaluations_holm'))} |")


def gait() -> None:
    rows = load("ablation_gait.json")
    if not rows:
        return
    print("\n## Gait ablation (`experiments/ablation.py gait`)")
    run_note("ablation_gait.json", ("horizon", "ants", "archive", "iterations", "seeds"))
    r0 = rows[0]
    print(f"\n### {r0['problem']}, native MuJoCo, nominal world, {r0['ants']} ants x "
          f"{r0['iterations']} iterations, {r0['seeds']} seeds\n")
    print("| cell | best distance m, mean [95% CI] | at half the budget | Δ vs default | "
          "better/worse seeds | p (Wilcoxon) | p Holm |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        bw = r.get("better_worse_seeds")
        print(f"| {r['cell']} | {r['distance_mean']:.3f} [{r['distance_ci_low']:.3f}, "
              f"{r['distance_ci_high']:.3f}] | {r['distance_at_half']:.3f} | "
              f"{num(r.get('delta_vs_ref'), '+.3f')} | {f'{bw[0]}/{bw[1]}' if bw else '-'} | "
              f"{p_fmt(r.get('p'))} | {p_fmt(r.get('p_holm'))} |")


def cec() -> None:
    rows = load("cec2006.json")
    if not rows:
        return
    print("\n## CEC2006")
    run_note("cec2006.json", ("budget", "runs", "method"))
    print("\n### CEC2006 (25 runs, 500,000 evaluations, success = feasible, f - f* <= 1e-4)\n")
    print("| problem | mode | success | SP charged | SP finite-diff. (point) | "
          "SP finite-diff. (per function) | εDE SP | best CEC2006 SP |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['problem']} ({r['paper_name']}) | {r['mode']} | "
              f"{r['successes']}/{r['runs']} | {num(r['sp_charged'], ',.0f')} | "
              f"{num(r['sp_fd'], ',.0f')} | {num(r['sp_fd_per_function'], ',.0f')} | "
              f"{r['eps_de_sp']:,} | {r['best_cec2006_sp']:,} |")


def paper() -> None:
    if any((RESULTS / f"paper/{n}.json").exists()
           for n in ("table1_tsp", "table2", "table3", "fig1", "fig4", "fig9")):
        print("\n## The paper's tables (`experiments/paper.py`)")
    t1 = load("paper/table1_tsp.json")
    if t1:
        run_note("paper/table1_tsp.json", ("instance", "tours", "ants", "seeds"))
        print(f"\n### Table 1 (TSP {t1[0]['instance']}, no local search, "
              f"{t1[0]['iterations'] * t1[0]['ants']:,} tours, target "
              f"{t1[0]['target_gap_percent']:g} % above the optimum)\n")
        print("| algorithm | s/iteration per run | iterations to convergence | hit target | "
              "iterations (tours) to target | s to target | final gap % [CI] | stuck | "
              "p vs EACO paper preset |")
        print("|---|---|---|---|---|---|---|---|---|")
        for r in t1:
            print(f"| {r['algorithm']} | {r['seconds_per_iteration_per_run']:.2e} | "
                  f"{r['iterations_to_convergence_mean']:.0f} | {r['success_rate']:.2f} | "
                  f"{num(r['iterations_to_target_mean'], '.0f')} "
                  f"({num(r.get('tours_to_target_mean'), ',.0f')}) | "
                  f"{num(r['seconds_to_target_mean'], '.3f')} | {r['final_gap_mean']:.2f} "
                  f"[{r['final_gap_ci_low']:.2f}, {r['final_gap_ci_high']:.2f}] | "
                  f"{r['stuck_fraction']:.2f} | {p_fmt(r.get('p_vs_eaco_paper'))} |")
    t2 = load("paper/table2.json")
    if t2:
        run_note("paper/table2.json", CON_KEYS)
        print("\n### Table 2 (G1-G4, derivative-free unless said, "
              f"{t2[0]['budget']:,} evaluations, {t2[0]['seeds']} seeds)\n")
        print("| problem | algorithm | success | iterations (evaluations) to target | "
              "s to target | mean best [CI] | median best | feasible | p vs EACO (d.-f.) | "
              "paper: iterations, mean best |")
        print("|---|---|---|---|---|---|---|---|---|---|")
        for r in t2:
            paper_col = (f"{r['paper_iterations']}, {r['paper_mean_best']}"
                         if r["algorithm"] in ("GA (LX-PM)", "SA", "EACO (derivative-free)")
                         else "")
            print(f"| {r['problem']} | {r['algorithm']} | {r['success_rate']:.2f} | "
                  f"{num(r['iterations_to_target_mean'], '.0f')} "
                  f"({num(r['evaluations_to_target_mean'], ',.0f')}) | "
                  f"{num(r['seconds_to_target_mean'], '.2f')} | "
                  f"{num(r.get('best_mean'), '.6g')} [{num(r.get('best_ci_low'), '.6g')}, "
                  f"{num(r.get('best_ci_high'), '.6g')}] | {num(r.get('best_median'), '.6g')} | "
                  f"{r['feasible_rate']:.2f} | {p_fmt(r.get('p_vs_eaco_df'))} | {paper_col} |")
    t3 = load("paper/table3.json")
    if t3:
        run_note("paper/table3.json", ("budget", "seeds"))
        print("\n### Table 3 (G1 = g01)\n")
        print("| mode | q0, rho, p_c, p_m | success | iterations to target [CI] | "
              "expected iterations | mean best | paper: iterations, best |")
        print("|---|---|---|---|---|---|---|")
        for r in t3:
            print(f"| {r['mode']} | {r['q0']}, {r['rho']}, {r['p_crossover']}, "
                  f"{r['p_mutation']} | {r['success_rate']:.2f} | "
                  f"{num(r['iterations_to_target_mean'], '.1f')} "
                  f"[{num(r.get('iterations_to_target_ci_low'), '.1f')}, "
                  f"{num(r.get('iterations_to_target_ci_high'), '.1f')}] | "
                  f"{num(r['expected_iterations_to_target'], '.1f')} | "
                  f"{r['best_mean']:.5f} | {r['paper_iterations']}, "
                  f"{r['paper_optimal_solution']} |")
    for name, title, keys in (
            ("fig1", "Fig. 1", ("instance", "tours", "ants", "seeds")),
            ("fig4", "Fig. 4A (path among 10 obstacles; crossover rate)",
             ("path_world", "path_ants", "path_iterations", "seeds")),
            ("fig9", "Fig. 9", ("instance", "tours", "ants", "seeds"))):
        rows = load(f"paper/{name}.json")
        if not rows:
            continue
        print(f"\n### {title}")
        run_note(f"paper/{name}.json", keys)
        print()
        for r in rows:
            keep = {k: v for k, v in r.items() if not isinstance(v, list)}
            print("- " + ", ".join(f"{k} {num(v, '.3g') if isinstance(v, float) else v}"
                                   for k, v in keep.items()))


def main() -> None:
    global RESULTS
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--results", type=Path, default=RESULTS, help="folder of the JSONs")
    ap.add_argument("--out", type=Path, help="markdown file (default: stdout)")
    args = ap.parse_args()
    RESULTS = args.results
    with contextlib.ExitStack() as stack:
        if args.out is not None:
            sys.stdout = stack.enter_context(args.out.open("w"))
        try:
            print("# Evidence tables\n\n_Generated file: do not edit. Regenerate with "
                  "`python experiments/evidence_report.py --out docs/evidence.md` from the "
                  "result JSONs under `experiments/results/` (how each was run: the JSON's "
                  "`meta`)._")
            tsp()
            constrained()
            gait()
            cec()
            paper()
        finally:
            sys.stdout = sys.__stdout__


if __name__ == "__main__":
    main()
