"""``rfsw-plan calibrate``: registration, model choice and held-out score of a robot from
measurement files (:mod:`rfsw_plan.validation.calibrate`)."""

from __future__ import annotations

import argparse

from rfsw_plan.cli.numbers import count

NAME = "calibrate"
HELP = ("calibrate a robot from laser-tracker or motion-capture files: registration, geometry "
        "and effects chosen by held-out cross-validation, calibrated robot file")

EPILOG = """\
The model is chosen on the --data files only: the geometry (joint zero offsets, link errors)
and then, one at a time, the library effect the workbench's diagnosis ranks best by
cross-validation by pose group (equal joint values = one group), while it is significant.
Each --data file's device frame is registered separately; the marker on the tool is common.
heldout_rms_mm leaves one pose group out at a time (10 folds by pose group beyond 60 groups),
the whole fit redone without it, as the 3-D RMS over every marker. Then score other files:
  rfsw-plan validate --robot FITTED.toml --data OTHER --columns C.toml --frame device --json
(only OTHER's device frame is registered again; --keep-registration holds it too).
"""


def register(parser: argparse.ArgumentParser) -> None:
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = EPILOG
    parser.add_argument("--robot", required=True, help="bundled robot name or robot TOML file")
    parser.add_argument("--data", required=True, action="append", metavar="FILE",
                        help="training measurement file (CSV or .mat; repeatable, each with its "
                        "own device frame)")
    parser.add_argument("--score", action="append", default=[], metavar="OTHER",
                        help="also score this file with the calibrated model, only its device "
                        "frame registered again (as validate's rms_3d_mm; repeatable; never "
                        "used to choose or fit)")
    parser.add_argument("--columns", metavar="FILE.toml",
                        help="column map of the files (docs/formats/measurements.md)")
    parser.add_argument("--frame", choices=("base", "device"),
                        help="frame of the measured positions (default: the column map's, "
                        "else base)")
    parser.add_argument("--save-robot", metavar="FITTED.toml",
                        help="write the calibrated robot file")
    parser.add_argument("--name", default=None, help="robot name in the --save-robot file")
    parser.add_argument("-o", "--output", metavar="DIR",
                        help="folder for calibrate.json (default: none)")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--geometry", default="kinematic_offsets,link_errors",
                        metavar="EFFECTS",
                        help="effects always fitted, comma-separated, or 'none' (default "
                        "kinematic_offsets,link_errors: joint zeros and the links' own errors)")
    parser.add_argument("--max-effects", type=count(0, 10), default=4,
                        help="at most this many effects added beyond the geometry (default 4)")
    parser.add_argument("--folds", type=count(2, 1000), default=5,
                        help="folds of the selection's cross-validation (default 5)")
    parser.add_argument("--heldout-folds", type=count(2, 100_000), default=None,
                        help="folds by pose group of the held-out figure (default: leave one "
                        "pose group out up to 60 groups, else 10)")
    parser.add_argument("--every", type=count(1, 10_000), default=1,
                        help="keep every N-th pose group of each file (a deterministic "
                        "subsample; default 1 = all)")
    parser.add_argument("--keep-registration", action="store_true",
                        help="the fitted registration holds for other files (a fixed "
                        "motion-capture body) instead of being registered again per file")
    parser.add_argument("--seed", type=count(0, 2**32 - 1), default=0,
                        help="seed of the fold split (default 0)")


def run(args: argparse.Namespace) -> int:
    from rfsw_plan.files import prepare_output_dir, prepare_output_file, strict_json
    from rfsw_plan.validation.calibrate import CalibrationRequest
    from rfsw_plan.validation.calibrate import run as calibrate

    save = str(prepare_output_file(args.save_robot, "--save-robot")) if args.save_robot else None
    out = prepare_output_dir(args.output) if args.output else None
    geometry = () if args.geometry.strip() == "none" else tuple(
        g.strip() for g in args.geometry.split(",") if g.strip())
    request = CalibrationRequest(
        robot=args.robot, geometry=geometry, data=tuple(args.data), columns=args.columns,
        frame=args.frame,
        max_effects=args.max_effects, folds=args.folds, heldout_folds=args.heldout_folds,
        every=args.every, keep_registration=args.keep_registration, save_robot=save,
        name=args.name, seed=args.seed, score=tuple(args.score))
    result = calibrate(request)
    if out is not None:
        result.write(out)
    if args.json:
        print(strict_json(result.to_json()))
        return 0
    j = result.to_json()
    print(f"calibrated {j['parent_robot']} on {len(args.data)} file(s), {j['samples']} samples, "
          f"{j['markers_per_pose']} marker(s) per pose")
    for s in j["selection"]:
        print(f"  {s['added']:<50} training CV {s['training_cv_rms_mm']:.3f} mm/axis")
    print(f"held out ({j['heldout_scheme']}, {j['heldout_pose_groups']} pose groups): "
          f"{j['heldout_rms_mm']:.3f} mm 3-D RMS over markers; fit {j['fit_rms_mm']:.3f} mm; "
          f"registration only {j['registration_only_rms_mm']:.3f} mm")
    iso = j["iso9283"]
    if j["repeatability_mm"] is not None:
        print(f"repeatability RP {iso['RP_mean_mm']:.3f} mm mean, {iso['RP_max_mm']:.3f} mm "
              f"worst pose ({iso['repeated_groups']} repeated poses); AP {iso['AP_mean_mm']:.3f}"
              f" mm mean, {iso['AP_max_mm']:.3f} mm worst (held out)")
    print(f"effects: {', '.join(j['effects']) or 'none'}")
    for sc in j["scores"]:
        print(f"scored {sc['data']}: {sc['rms_3d_mm']:.3f} mm 3-D RMS over {sc['samples']} "
              "samples, only its device frame registered again")
    if result.saved is not None:
        print(f"wrote {result.saved}")
    return 0
