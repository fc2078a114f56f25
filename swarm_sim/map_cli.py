"""``swarm-map WORLD``: rasterise a Gazebo world into a nav2 map_server map (YAML + PGM).

Examples::

    swarm-map slim_blockage                      # writes slim_blockage.yaml + .pgm here
    swarm-map my_hall.world --resolution 0.1 --output maps/my_hall

Exit codes (docs/reference/contract.md#s2): 0 written, 2 bad input (one line on stderr), 1 runtime
failure.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from swarm_common import cli
from swarm_common.errors import InputError, run_cli
from swarm_scene.map_io import save_map
from swarm_scene.poi import poi_for_world
from swarm_scene.rasterize import rasterize_world
from swarm_scene.spawn import choose_free_region
from swarm_scene.world import (
    BAND_TOP,
    FLOOR_TOLERANCE,
    describe_skipped,
    floor_shapes,
    load_world,
)

PROG = "swarm-map"


def build_parser() -> argparse.ArgumentParser:
    """The command line of ``swarm-map``."""
    parser = cli.ArgumentParser(
        prog=PROG,
        description="Rasterise a Gazebo world (SDF) into a nav2 map_server map: PREFIX.yaml + "
                    "PREFIX.pgm (trinary: 254 free, 0 occupied). A cell is occupied when any "
                    "collision shape between --z-min and --z-max overlaps it.",
        epilog="Example: swarm-map slim_blockage --output maps/slim_blockage",
    )
    parser.add_argument("world", metavar="WORLD",
                        help="a world name under worlds/ (e.g. slim_blockage) or a path to a "
                             ".world/.sdf file")
    parser.add_argument("--resolution", type=cli.positive_float, default=0.05, metavar="M",
                        help="cell size [m/cell] (default: 0.05)")
    parser.add_argument("--output", "-o", metavar="PREFIX", default=None,
                        help="output path without suffix (default: the world's name, in the "
                             "current directory)")
    parser.add_argument("--padding", type=cli.non_negative_float, default=0.5, metavar="M",
                        help="free margin around the world's shapes [m] (default: 0.5)")
    parser.add_argument("--z-min", type=cli.finite_float, default=FLOOR_TOLERANCE, metavar="M",
                        help="bottom of the robots' height band [m]: a shape whose top is at or "
                             "below it is floor, driven on (default: "
                             f"{FLOOR_TOLERANCE:g})")
    parser.add_argument("--z-max", type=cli.finite_float, default=BAND_TOP, metavar="M",
                        help=f"top of the robots' height band [m] (default: {BAND_TOP:g})")
    return parser


def _run(argv: list[str] | None) -> int:
    args = build_parser().parse_args(argv)
    if args.z_max <= args.z_min:
        raise InputError(f"--z-max: must be above --z-min ({args.z_min:g} m), got "
                         f"{args.z_max:g}")
    prefix = Path(args.output) if args.output else None
    if prefix is not None and prefix.suffix in (".yaml", ".pgm"):
        prefix = prefix.with_suffix("")
    if prefix is not None and not prefix.parent.is_dir():
        raise InputError(f"--output: directory '{prefix.parent}' does not exist")
    world = load_world(args.world)
    skipped = describe_skipped(world)
    if skipped is not None:
        print(f"{PROG}: warning: {skipped}", file=sys.stderr)
    occ = rasterize_world(world, resolution=args.resolution, padding=args.padding,
                          z_min=args.z_min, z_max=args.z_max)
    prefix = prefix or Path(world.name)
    yaml_path, image_path = save_map(occ, prefix)
    occupied = int((occ.data == 100).sum())
    print(f"wrote {yaml_path} and {image_path}: {occ.width} x {occ.height} cells at "
          f"{occ.resolution:g} m/cell, origin ({occ.origin[0]:g}, {occ.origin[1]:g}) m, "
          f"{occupied} occupied, from {len(world.shapes)} shapes of {world.source}")
    floor = [*world.floor, *(s.name for s in floor_shapes(world, args.z_min))]
    if floor:
        print(f"floor (driven on, not obstacles: ground planes, heightmaps and shapes whose top "
              f"is at or below {args.z_min:g} m): {_names(floor)}")
    print(spawn_line(world.source, occ))
    return 0


def _names(names: list[str], limit: int = 6) -> str:
    shown = ", ".join(names[:limit])
    return shown + (f" and {len(names) - limit} more" if len(names) > limit else "")


def spawn_line(world_path: Path, occ) -> str:
    """One line saying where ``swarm-up`` spawns robots in this world
    (docs/reference/contract.md#s4).

    Args:
        world_path: the world file; its points of interest are the ``.yaml`` beside it.
        occ: the map robots spawn on (used when the world has no spawn area).
    """
    poi = poi_for_world(world_path)
    if poi is not None and poi.spawn is not None:
        sp = poi.spawn
        x0, y0, x1, y1 = sp.area
        return (f"spawn: the spawn area of {world_path.with_suffix('.yaml').name}: a "
                f"{sp.spacing:g} m grid from ({sp.origin[0]:g}, {sp.origin[1]:g}) within x "
                f"{x0:g}..{x1:g}, y {y0:g}..{y1:g} m ({sp.grid_points().shape[0]} nodes before "
                "the wall check)")
    region = choose_free_region(occ)
    why = "no points of interest" if poi is None else "no spawn area in its points of interest"
    return (f"spawn: {why}: robots spawn on a 1 m grid (wider for robots over 0.9 m across) in "
            f"{region.describe()}, nearest first to its clearest "
            f"point ({region.origin[0]:.2f}, {region.origin[1]:.2f}) m, {region.clearance:.2f} m "
            "from the nearest obstacle")


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``swarm-map``; returns the exit code (0, 1 or 2)."""
    return run_cli(PROG, lambda: _run(argv))


if __name__ == "__main__":
    sys.exit(main())
