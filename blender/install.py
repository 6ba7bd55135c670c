"""Install the nephele add-on into Blender, in one command.

    python blender/install.py                 # zip it and install with `blender` on PATH
    python blender/install.py --blender PATH  # a given Blender executable
    python blender/install.py --zip-only      # just write target/nephele_blender.zip

It zips blender/nephele_blender/ and runs Blender in the background to install that zip as an
extension (Blender 4.2+: `blender --command extension install-file -r user_default -e ZIP`),
falling back to the legacy add-on install (`bpy.ops.preferences.addon_install`) and enabling it.
Without a Blender executable, a Python that has the `bpy` module (the `bpy` wheel: Blender as a
Python module) installs and enables it in-process, into the same user folders
(`BLENDER_USER_SCRIPTS` / `BLENDER_USER_CONFIG` when set).
"""

import argparse
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent


def make_zip(dest: Path) -> Path:
    dest.parent.mkdir(parents=True, exist_ok=True)
    with zipfile.ZipFile(dest, "w", zipfile.ZIP_DEFLATED) as z:
        for f in sorted((HERE / "nephele_blender").rglob("*")):
            if f.is_file() and "__pycache__" not in f.parts:
                z.write(f, Path("nephele_blender") / f.relative_to(HERE / "nephele_blender"))
    return dest


LEGACY = """
import bpy, sys
bpy.ops.preferences.addon_install(filepath=sys.argv[-1], overwrite=True)
bpy.ops.preferences.addon_enable(module="nephele_blender")
bpy.ops.wm.save_userpref()
"""


def install_with_bpy(zpath: Path) -> int:
    """Install and enable the add-on with this Python's `bpy` module (no Blender executable)."""
    try:
        import bpy  # noqa: PLC0415 (only this route needs it)
    except ImportError:
        print("no `blender` on PATH and no `bpy` module in this Python: pass --blender PATH, "
              "run this script with a Python that has the bpy wheel (pip install bpy), or "
              "install the zip from Blender's Preferences > Get Extensions > Install from Disk",
              file=sys.stderr)
        return 1
    bpy.ops.preferences.addon_install(filepath=str(zpath), overwrite=True)
    bpy.ops.preferences.addon_enable(module="nephele_blender")
    bpy.ops.wm.save_userpref()
    print(f"installed and enabled with the bpy module (Blender {bpy.app.version_string})")
    return 0


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--blender", default=shutil.which("blender"), help="Blender executable")
    p.add_argument("--zip-only", action="store_true")
    args = p.parse_args()
    zpath = make_zip(ROOT / "target" / "nephele_blender.zip")
    print(f"wrote {zpath}")
    if args.zip_only:
        return 0
    if not args.blender:
        return install_with_bpy(zpath)
    ext = subprocess.run([args.blender, "--command", "extension", "install-file",
                          "-r", "user_default", "-e", str(zpath)])
    if ext.returncode == 0:
        print("installed and enabled as an extension")
        return 0
    legacy = subprocess.run([args.blender, "-b", "--factory-startup", "--python-expr", LEGACY,
                             "--", str(zpath)])
    return legacy.returncode


if __name__ == "__main__":
    sys.exit(main())
