#!/usr/bin/env python3
"""A bird's-eye picture of hazard episodes from `actor eval --suite hazards --trajectories-out`:
one panel per run (seed), each agent's trajectory around the same hazard, the route's lane, and
what stood in the way. Every run of the scenario is drawn (no choosing of a telling one).

  scripts/episode_figure.py --trajectories FILE [--scenario stalled_car] [--keep KEPT.jsonl] --out FIGURE.svg

Each panel is turned so that the route runs left to right at the hazard point (the hazard at x = 0)
and shows WINDOW metres before and after it. Standard library only.
"""

import argparse
import json
import math
import sys
from pathlib import Path

WINDOW = (-45.0, 35.0)  # metres along the route's direction at the hazard point
HALF_HEIGHT = 11.0  # metres either side of the route
SCALE = 9.0  # pixels per metre
LANE_WIDTH = 3.5
COLOURS = ["#555555", "#1a9641", "#2c7bb6", "#d7191c", "#fdae61", "#7b3294", "#018571"]
BODY_FILL = {"hazard_car": "#e41a1c", "parked": "#9e9e9e", "parked_car": "#9e9e9e", "cone": "#ff7f00", "barrier": "#b35806"}


def load(path, scenario):
    runs = [json.loads(line) for line in Path(path).read_text().splitlines() if line.strip()]
    runs = [r for r in runs if r["scenario"] == scenario]
    if not runs:
        sys.exit(f"episode_figure.py: {path} has no run of scenario `{scenario}`")
    return runs


def frame(run):
    """The hazard point and the route's direction there: the panel's origin and x axis."""
    px, py = run["hazard_point"] or run["route"][len(run["route"]) // 2]
    pts = run["route"]
    k = min(range(len(pts)), key=lambda i: (pts[i][0] - px) ** 2 + (pts[i][1] - py) ** 2)
    a, b = pts[max(0, k - 3)], pts[min(len(pts) - 1, k + 3)]
    return px, py, math.atan2(b[1] - a[1], b[0] - a[0])


def to_panel(f, x, y):
    px, py, th = f
    dx, dy = x - px, y - py
    c, s = math.cos(-th), math.sin(-th)
    return dx * c - dy * s, dx * s + dy * c


def px_of(u, v, ox, oy):
    return ox + (u - WINDOW[0]) * SCALE, oy + (HALF_HEIGHT - v) * SCALE


def polyline(points, f, ox, oy):
    return " ".join("{:.1f},{:.1f}".format(*px_of(*to_panel(f, p[0], p[1]), ox, oy)) for p in points)


def body_svg(b, f, ox, oy, outline=None):
    cx, cy = b["centre"]
    if b["kind"] == "walker":
        x, y = px_of(*to_panel(f, cx, cy), ox, oy)
        return f'<circle cx="{x:.1f}" cy="{y:.1f}" r="4" fill="#984ea3"/>'
    hx, hy = b["half"]
    a = b["angle"]
    corners = []
    for sx, sy in [(1, 1), (-1, 1), (-1, -1), (1, -1)]:
        lx, ly = sx * hx, sy * hy
        corners.append((cx + lx * math.cos(a) - ly * math.sin(a), cy + lx * math.sin(a) + ly * math.cos(a)))
    if outline:
        return f'<polygon points="{polyline(corners, f, ox, oy)}" fill="none" stroke="{outline}" stroke-width="1.5" stroke-dasharray="3 2"/>'
    return f'<polygon points="{polyline(corners, f, ox, oy)}" fill="{BODY_FILL.get(b["kind"], "#999")}" stroke="#333" stroke-width="0.5"/>'


def lane_band(route, f, ox, oy):
    """The route's lane: its centre line offset by half a lane to each side, as one polygon."""
    left, right = [], []
    for i, p in enumerate(route):
        a, b = route[max(0, i - 1)], route[min(len(route) - 1, i + 1)]
        th = math.atan2(b[1] - a[1], b[0] - a[0])
        nx, ny = -math.sin(th) * LANE_WIDTH / 2, math.cos(th) * LANE_WIDTH / 2
        left.append((p[0] + nx, p[1] + ny))
        right.append((p[0] - nx, p[1] - ny))
    return f'<polygon points="{polyline(left + right[::-1], f, ox, oy)}" fill="#eeeeee" stroke="none"/>'


def outcome(run):
    return ", ".join(run["infractions"]) if run["infractions"] else "arrived, no infraction" if run["driving_score"] >= 0.999 else "no infraction"


def figure(runs, scenario, title):
    agents = list(dict.fromkeys(r["agent"] for r in runs))
    seeds = sorted({r["seed"] for r in runs})
    w = (WINDOW[1] - WINDOW[0]) * SCALE
    h = 2 * HALF_HEIGHT * SCALE
    legend_w = 520
    top = 62
    row_h = h + 34
    width, height = int(w + legend_w + 30), int(top + row_h * len(seeds) + 10)
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" font-family="sans-serif" font-size="12">',
           '<rect width="100%" height="100%" fill="white"/>',
           f'<text x="10" y="18" font-size="14" font-weight="bold">{title}</text>',
           f'<text x="10" y="36" fill="#555">The route runs left to right; the hazard point at 0 m. Grey band: the route\'s lane. '
           'Red: the hazard\'s car; grey: parked cars. × where a run ended in a collision;</text>',
           '<text x="10" y="52" fill="#555">dashed boxes in a run\'s colour: the traffic within 12 m of it at its end.</text>']
    for row, seed in enumerate(seeds):
        ox, oy = 10, top + row * row_h + 16
        out.append(f'<text x="{ox}" y="{oy - 4}" font-weight="bold">seed {seed}</text>')
        clip = f"clip{row}"
        out.append(f'<clipPath id="{clip}"><rect x="{ox}" y="{oy}" width="{w}" height="{h}"/></clipPath>')
        out.append(f'<rect x="{ox}" y="{oy}" width="{w}" height="{h}" fill="#fafafa" stroke="#ccc"/>')
        out.append(f'<g clip-path="url(#{clip})">')
        first = next(r for r in runs if r["seed"] == seed)
        f = frame(first)
        out.append(lane_band(first["route"], f, ox, oy))
        out.append(f'<polyline points="{polyline(first["route"], f, ox, oy)}" fill="none" stroke="#bbb" stroke-dasharray="4 3"/>')
        for b in first["bodies_start"]:
            out.append(body_svg(b, f, ox, oy))
        for k, agent in enumerate(agents):
            run = next((r for r in runs if r["seed"] == seed and r["agent"] == agent), None)
            if run is None:
                continue
            c = COLOURS[k % len(COLOURS)]
            out.append(f'<polyline points="{polyline(run["ego"], f, ox, oy)}" fill="none" stroke="{c}" stroke-width="2" opacity="0.85"/>')
            for b in run["bodies_end"]:
                if b["kind"] == "traffic":
                    out.append(body_svg(b, f, ox, oy, outline=c))
            if any("collision" in i for i in run["infractions"]):
                x, y = px_of(*to_panel(f, run["ego"][-1][0], run["ego"][-1][1]), ox, oy)
                out.append(f'<text x="{x:.1f}" y="{y + 5:.1f}" text-anchor="middle" font-size="16" font-weight="bold" fill="{c}">×</text>')
        out.append("</g>")
        for t in range(int(WINDOW[0] // 10 * 10) + 10, int(WINDOW[1]) + 1, 10):
            x, _ = px_of(t, 0, ox, oy)
            out.append(f'<text x="{x:.1f}" y="{oy + h + 12:.1f}" text-anchor="middle" fill="#777" font-size="10">{t} m</text>')
        lx = ox + w + 14
        for k, agent in enumerate(agents):
            run = next((r for r in runs if r["seed"] == seed and r["agent"] == agent), None)
            if run is None:
                continue
            y = oy + 14 + k * 17
            c = COLOURS[k % len(COLOURS)]
            out.append(f'<line x1="{lx}" y1="{y - 4}" x2="{lx + 16}" y2="{y - 4}" stroke="{c}" stroke-width="3"/>')
            out.append(f'<text x="{lx + 22}" y="{y}">{agent}: {run["driving_score"]:.2f} ({outcome(run)})</text>')
    out.append("</svg>")
    return "\n".join(out) + "\n"


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--trajectories", required=True, help="the JSON lines of `actor eval --trajectories-out`")
    p.add_argument("--scenario", default="stalled_car", help="the suite's scenario to draw (default stalled_car)")
    p.add_argument("--title", default=None)
    p.add_argument("--keep", default=None, help="also write the scenario's runs here (a compact copy that redraws the figure)")
    p.add_argument("--out", required=True, help="the SVG to write")
    a = p.parse_args()
    runs = load(a.trajectories, a.scenario)
    if a.keep:
        Path(a.keep).parent.mkdir(parents=True, exist_ok=True)
        Path(a.keep).write_text("".join(json.dumps(r, separators=(",", ":")) + "\n" for r in runs))
    svg = figure(runs, a.scenario, a.title or f"{a.scenario}: every agent's run around the same hazard, per seed")
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    Path(a.out).write_text(svg)
    print(f"wrote {a.out}: {len({r['seed'] for r in runs})} runs of {a.scenario}, {len({r['agent'] for r in runs})} agents", file=sys.stderr)


if __name__ == "__main__":
    main()
