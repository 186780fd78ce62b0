"""The benchmark's Markdown table."""

from __future__ import annotations

from typing import Any

ROWS = (
    ("SAC update (µs)", "update_us", "update", "{:.0f}"),
    ("reward-model epoch (µs)", "reward_epoch_us", "reward_epoch", "{:.0f}"),
    ("loop (env steps/s)", "loop_steps_per_s", "loop", "{:.1f}"),
    ("collection step: action, simulator, store (µs)", "collect_us", None, "{:.0f}"),
    ("projected full run (min)", "projected_full_run_s", "projected_full_run", "{:.1f}"),
    ("feedback session (s)", "session_s", None, "{:.2f}"),
    ("evaluation, time training waits (s)", "eval_episode_s", None, "{:.2f}"),
    ("CUDA graph capture (s)", "capture_s", None, "{:.2f}"),
)


def format_markdown(result: dict[str, Any]) -> str:
    s = result["settings"]
    variants = result["variants"]
    fast = [name for name in variants if name != "reference"]
    header = ["", *variants, *(f"{name} / reference" for name in fast)]
    lines = [
        f"# seqrank bench: {s['task']} on {result['device']}",
        "",
        f"Command: `{result.get('command', 'seqrank bench')}` (torch {result['torch']}).",
        f"Sizes ({s['scale']} preset): {s['layers']} x {s['hidden']} networks, batch "
        f"{s['batch']}; reward ensemble {s['reward_ensemble']} x {s['reward_hidden']}. "
        f"Medians of {s['repeats']} interleaved rounds ({s['updates']} updates, "
        f"{s['reward_epochs']} reward epochs, {s['loop_steps']} loop steps per round).",
        "",
        "| " + " | ".join(header) + " |",
        "|" + "---|" * len(header),
    ]
    for label, key, ratio_key, fmt in ROWS:
        if key == "capture_s" and not str(result["device"]).startswith("cuda"):
            continue  # CUDA graphs are captured on CUDA only
        scale = 1 / 60 if key == "projected_full_run_s" else 1
        cells = [fmt.format(variants[name][key] * scale) for name in variants]
        for name in fast:
            ratio = result["ratios"][name].get(ratio_key) if ratio_key else None
            cells.append(f"{ratio:.2f}x" if ratio is not None else "")
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    lines += [
        "",
        f"Ratios are how many times faster than the reference. The projection is {s['steps']} "
        f"steps at the loop rate plus {s['sessions']} feedback sessions plus an evaluation "
        f"of {s['eval_episodes']} episodes every {s['eval_every']} steps.",
    ]
    if "full_run" in result:
        run = result["full_run"]
        lines.append(
            f"Measured full run (fast path): {run['steps']} steps in "
            f"{run['wall_s'] / 60:.1f} min, final evaluation return "
            f"{run['final_eval_return']:.1f}, {run['asked']} questions."
        )
    return "\n".join(lines) + "\n"
