#!/usr/bin/python3
"""A remote simulation: a ball dropped onto the ground on a fulcrum-server, its height over time.

    /usr/bin/python3 height_over_time.py --server 127.0.0.1:50051 --out ball

writes ball.csv (tick, time in s, height in m, vertical speed in m/s) and ball.svg (a plot);
with matplotlib installed (python3-matplotlib), ball.png too. The world steps `--every` ticks at
a time and the frame stream delivers the frame of each step, so every sample is taken: a
reader that keeps up with its own steps misses nothing.
"""

import argparse
import csv
import sys

import fulcrum


def ball_scene(height, restitution):
    return {
        "name": "bouncing ball",
        "settings": {"gravity": {"x": 0, "y": -10}, "dt": 1 / 60},
        "builders": [{"ground": {"halfWidth": 10, "top": 0}}],
        "bodies": [{
            "type": "BODY_TYPE_DYNAMIC",
            "position": {"x": 0, "y": height},
            "shapes": [{"circle": {"radius": 0.5}, "restitution": restitution}],
        }],
    }


def simulate(client, seconds, every, height, restitution):
    """Rows of (tick, t, height, vy) of the ball (body 1; body 0 is the ground)."""
    rows = []
    with client.create_world(ball_scene(height, restitution)) as world:
        dt = world.info().settings.dt
        last = round(seconds / dt)
        for frame in world.frames(every=every, until_tick=last):
            state = frame.body(fulcrum.Handle(1, 1))
            rows.append((frame.tick, frame.tick * dt, state.position[1],
                         state.linear_velocity[1]))
            if frame.tick < last:
                world.step(every)
    return rows


def write_svg(path, rows, title):
    """A line plot of height against time, as plain SVG (no plotting library needed)."""
    width, height, pad = 640, 360, 40
    t_max = max(r[1] for r in rows) or 1.0
    y_max = max(r[2] for r in rows) or 1.0

    def xy(row):
        return (pad + (width - 2 * pad) * row[1] / t_max,
                height - pad - (height - 2 * pad) * row[2] / y_max)

    points = " ".join(f"{x:.1f},{y:.1f}" for x, y in map(xy, rows))
    with open(path, "w", encoding="utf-8") as out:
        out.write(
            f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}">\n'
            f'<rect width="100%" height="100%" fill="white"/>\n'
            f'<text x="{pad}" y="24" font-family="sans-serif" font-size="14">{title}</text>\n'
            f'<line x1="{pad}" y1="{height - pad}" x2="{width - pad}" y2="{height - pad}" '
            f'stroke="black"/>\n'
            f'<line x1="{pad}" y1="{pad}" x2="{pad}" y2="{height - pad}" stroke="black"/>\n'
            f'<text x="{width - pad}" y="{height - 12}" font-family="sans-serif" font-size="12" '
            f'text-anchor="end">{t_max:.2f} s</text>\n'
            f'<text x="4" y="{pad}" font-family="sans-serif" font-size="12">{y_max:.1f} m</text>\n'
            f'<polyline fill="none" stroke="steelblue" stroke-width="2" points="{points}"/>\n'
            f'</svg>\n')


def write_png(path, rows, title):
    try:
        import matplotlib
    except ImportError:
        return False
    matplotlib.use("Agg")
    from matplotlib import pyplot
    figure, axes = pyplot.subplots(figsize=(8, 4.5))
    axes.plot([r[1] for r in rows], [r[2] for r in rows])
    axes.set(xlabel="time (s)", ylabel="height (m)", title=title)
    figure.savefig(path, dpi=100)
    return True


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--server", default="127.0.0.1:50051", help="HOST:PORT")
    parser.add_argument("--token-file", help="the server's --token-file")
    parser.add_argument("--out", default="height", help="output path without extension")
    parser.add_argument("--seconds", type=float, default=4.0)
    parser.add_argument("--every", type=int, default=2, help="ticks between samples")
    parser.add_argument("--height", type=float, default=10.0, help="drop height, m")
    parser.add_argument("--restitution", type=float, default=0.7)
    args = parser.parse_args(argv)

    try:
        with fulcrum.connect(args.server, token_file=args.token_file) as client:
            rows = simulate(client, args.seconds, args.every, args.height, args.restitution)
    except fulcrum.FulcrumError as error:
        print(f"height_over_time: {error}", file=sys.stderr)
        return 1
    with open(args.out + ".csv", "w", newline="", encoding="utf-8") as out:
        writer = csv.writer(out)
        writer.writerow(["tick", "t_s", "height_m", "vy_m_s"])
        writer.writerows(rows)
    title = f"ball dropped from {args.height} m, restitution {args.restitution}"
    write_svg(args.out + ".svg", rows, title)
    made = [args.out + ".csv", args.out + ".svg"]
    if write_png(args.out + ".png", rows, title):
        made.append(args.out + ".png")
    print(f"{len(rows)} samples to {', '.join(made)}; lowest {min(r[2] for r in rows):.3f} m")
    return 0


if __name__ == "__main__":
    sys.exit(main())
