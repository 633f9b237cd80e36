"""``rollfric render``: render a trajectory as synthetic 1000 Hz camera frames (argparse only:
heavy imports happen in the handler)."""

from __future__ import annotations

from rollfric.cli.helpformat import HelpFormatter, example

HELP = "render a trajectory as a synthetic camera recording (Zarr) with exact ground truth"


def register(sub) -> None:
    p = sub.add_parser(
        "render", help=HELP, description=(
            "Render a ball trajectory as the lab camera would have seen it (pyrender, "
            "headless) and store it as a Zarr recording: the clean render plus the seeded "
            "sensor model, applied when frames are read (same bytes on every read), and the "
            "exact ground truth per frame (projected ball centre and silhouette centre, "
            "radius, theta, cylinder centre, in pixels). TRAJ is a trajectory CSV written by "
            "`rollfric simulate` (with its .json sidecar) or a scenario TOML (simulated "
            "first). Lighting presets: thesis, dim, harsh, uneven, flat. Noise presets: none, "
            "realistic, noisy, 12bit, dark."),
        formatter_class=HelpFormatter,
        epilog=example("rollfric render traj.csv --out rec.zarr --export lab",
                       docs="docs/guide/render.md"))
    p.add_argument("trajectory", metavar="TRAJ", help="trajectory CSV or scenario TOML")
    p.add_argument("--out", required=True, metavar="REC.zarr", help="recording to write")
    p.add_argument("--lighting", default="thesis", help="lighting preset")
    p.add_argument("--noise", default="realistic", help="sensor noise preset")
    p.add_argument("--seed", type=int, default=0, help="seed of the sensor noise")
    p.add_argument("--projection", default="orthographic",
                   choices=["orthographic", "perspective"], help="camera model")
    p.add_argument("--working-distance-mm", type=float, default=500.0,
                   help="pinhole to ball plane (perspective only)")
    p.add_argument("--supersample", type=int, default=1,
                   help="ss x ss samples per pixel on top of 4x MSAA (2: the rendered silhouette "
                        "agrees with the truth to < 0.01 px; 1: ~0.015 px rms)")
    p.add_argument("--motion-blur", type=int, default=1, metavar="K",
                   help="sub-frames integrated over the exposure (1: none)")
    p.add_argument("--exposure-us", type=float, default=None,
                   help="exposure time (default: the noise preset's, 200 us)")
    p.add_argument("--bit-depth", type=int, choices=[8, 10, 12, 14], default=None,
                   help="sensor bit depth, 10-14 in 16-bit words (default: the noise preset's)")
    p.add_argument("--renderer", default="pyrender", choices=["pyrender", "mitsuba"],
                   help="pyrender: rasterised, fast; mitsuba: path traced, a physically based "
                        "steel ball (the extra rollfric[mitsuba], docs/how/renderers.md)")
    p.add_argument("--spp", type=int, default=None,
                   help="mitsuba: samples per pixel around the ball, a power of 4 "
                        "(default 256)")
    p.add_argument("--frames", type=int, default=None, help="render only the first N frames")
    p.add_argument("--workers", type=int, default=None,
                   help="render processes (default: CPUs, at most 2)")
    p.add_argument("--export", metavar="DIR", default=None,
                   help="also write a lab-style export: frames.tif, background.png, "
                        "setup.toml, truth.csv")
    p.add_argument("--overwrite", action="store_true",
                   help="replace an existing recording (a folder holding anything else is never "
                        "replaced) and the export's own files in an existing --export DIR "
                        "(other files there are left alone); without it an existing output is "
                        "refused before rendering (exit 2)")
    p.set_defaults(func=run)


def run(args) -> int:
    import dataclasses

    import synth
    from rollfric.output.folder import check_distinct, check_not_input
    from synth.export import check_export, export_recording
    from synth.pipeline import check_output

    # every destination checked before any work
    check_not_input(args.out, (args.trajectory,))
    check_output(args.out, overwrite=args.overwrite, what="--out")
    if args.export:
        check_distinct([args.out, args.export], "--out and --export")
        check_not_input(args.export, (args.trajectory,), "--export")
        check_export(args.export, overwrite=args.overwrite)

    scene = synth.SceneConfig(lighting=synth.lighting_preset(args.lighting),
                              supersample=args.supersample, motion_blur=args.motion_blur,
                              renderer=args.renderer)
    if args.spp is not None:
        scene = scene.replace(mitsuba_spp=args.spp)
    cam = dataclasses.replace(scene.camera, projection=args.projection,
                              working_distance=args.working_distance_mm * 1e-3)
    scene = scene.replace(camera=cam)
    sensor = synth.noise_preset(args.noise)
    if args.exposure_us is not None:
        sensor = sensor.replace(exposure=args.exposure_us * 1e-6)
    if args.bit_depth is not None:
        sensor = sensor.replace(bit_depth=args.bit_depth)
    path = synth.render(args.trajectory, args.out, scene=scene, sensor=sensor, seed=args.seed,
                        progress=True, workers=args.workers, overwrite=args.overwrite,
                        frames=args.frames)
    print(f"wrote {path}")
    if args.export:
        d = export_recording(path, args.export, progress=True, overwrite=args.overwrite)
        print(f"exported {d}")
    return 0
