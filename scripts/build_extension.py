#!/usr/bin/env python3
"""Build the TNCG15 MC Blender extension (4.2+) and a legacy add-on zip (3.4) in one command.

    python scripts/build_extension.py [--platform linux-x64 ...] [--no-download] [--output-dir dist]

1. pip-downloads the embreex and OpenImageIO wheels (and their dependencies except numpy, which
   Blender ships) for each platform into ./wheels/ (gitignored), and the denoiser's, pyoidn with
   cffi and pycparser (Intel Open Image Denoise: engine/film/denoise.py), for the platforms it has
   wheels for (Linux x64, Windows x64; about 88 MB each; --no-denoiser leaves it out), and the
   compiled kernels', numba with llvmlite (engine/core/backend.py), for Linux x64 (--no-numba
   leaves them out: the tracer then runs its NumPy kernels);
2. stages the extension: blender_manifest.toml (its ``wheels``/``platforms`` set to what was
   downloaded), the contents of mcrt_addon/ at the zip root, the tracer package engine/ copied
   as the sub-package ``tracer/`` (the add-on imports it relatively; see mcrt_addon/bridge.py), the
   user guide docs/*.md as ``docs/`` (the preferences' Documentation button);
3. builds and validates the zip with Blender's own blender_ext.py (shipped in the bpy wheel, or
   from a Blender 4.2+ binary: ``blender --command extension build``);
4. also writes dist/tncg15_mc-<version>-legacy.zip for "Install Add-on" in Blender 3.4: a folder
   tncg15_mc/ with the same files and, for Linux x64 (CPython 3.11), the wheels unpacked:
   vendor/numpy/ (numpy 1.26.4: Blender's own process imports it when its Python has none, as
   Debian's Blender 3.4) and vendor/worker/ (embreex, OpenImageIO, numba and the denoiser: only the render
   worker and denoiser processes import them, so embreex never meets Blender 3.4's Embree 3 and OIDN
   never loads into Blender's process; mcrt_addon/worker_python.py).
"""
import argparse
import glob
import os
import re
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import zipfile

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PACKAGES = ["embreex==4.4.0.post1", "OpenImageIO==3.0.21.0"]
# Intel Open Image Denoise for the Denoise option (engine/film/denoise.py; run by the worker Python),
# bundled unless --no-denoiser: pyoidn's wheels (py3-none, about 88 MB) exist for these platforms only.
# Its numpy dependency is Blender's (extension) or the legacy zip's numpy.  The same pins are what
# the preferences' "Install Denoiser" installs (mcrt_addon/denoiser_install.py).
DENOISER = ["pyoidn==2.5.1.0", "cffi==2.1.1", "pycparser==3.12"]     # the venv's (requirements.txt)
DENOISER_DEPS = ("pyoidn", "cffi", "pycparser")
DENOISER_PLATFORMS = {"linux-x64": "manylinux2014_x86_64", "windows-x64": "win_amd64"}
# numba's compiled kernels (engine/core/backend.py; the workers import it): CPython 3.11 wheels bundled
# for Linux x64 only (numba's own wheels are manylinux2014); numba's numpy is Blender's or the legacy zip's.
COMPILED = ["numba==0.60.0", "llvmlite==0.43.0"]                    # the venv's (requirements.txt)
COMPILED_DEPS = ("numba", "llvmlite")
COMPILED_PLATFORMS = {"linux-x64": "manylinux2014_x86_64"}
PLATFORM_TAGS = {                      # Blender platform -> pip --platform
    "linux-x64": "manylinux_2_28_x86_64",
    "windows-x64": "win_amd64",
    "macos-arm64": "macosx_11_0_arm64",
    "macos-x64": "macosx_10_15_x86_64",
}
EXCLUDED_DEPS = ("numpy",)
LEGACY_NUMPY = "numpy==1.26.4"          # the venv's; cp311 manylinux2014 wheels
LEGACY_PLATFORMS = ("manylinux_2_28_x86_64", "manylinux2014_x86_64", "manylinux_2_17_x86_64")
VENDOR_COMPRESSION = 1                 # deflate level of the unpacked wheels: 6 takes 1.5x the time for 5 % less
IGNORE = shutil.ignore_patterns("__pycache__", "*.pyc", "*.pyo")


def find_blender_ext():
    candidates = glob.glob(os.path.join(sysconfig.get_paths()["purelib"], "bpy", "*", "scripts", "addons_core",
                                        "bl_pkg", "cli", "blender_ext.py"))
    candidates += glob.glob(os.path.join(REPO, ".venv", "lib", "python3*", "site-packages", "bpy", "*", "scripts",
                                         "addons_core", "bl_pkg", "cli", "blender_ext.py"))
    return candidates[0] if candidates else None


def download_wheels(platforms, wheels_dir, offline, denoiser=True, compiled=True):
    os.makedirs(wheels_dir, exist_ok=True)
    for platform in platforms:
        if offline:
            continue
        common = ["--dest", wheels_dir, "--only-binary=:all:", "--python-version", "3.11", "--implementation", "cp",
                  "--quiet"]
        cmd = [sys.executable, "-m", "pip", "download", *PACKAGES, *common, "--platform", PLATFORM_TAGS[platform]]
        print("+", " ".join(cmd))
        subprocess.run(cmd, check=True)
        if denoiser and platform in DENOISER_PLATFORMS:      # pyoidn's Linux wheel is tagged manylinux2014
            cmd = [sys.executable, "-m", "pip", "download", *DENOISER, "--no-deps", *common,
                   "--platform", PLATFORM_TAGS[platform], "--platform", DENOISER_PLATFORMS[platform]]
            print("+", " ".join(cmd))
            subprocess.run(cmd, check=True)
        if compiled and platform in COMPILED_PLATFORMS:
            cmd = [sys.executable, "-m", "pip", "download", *COMPILED, "--no-deps", *common,
                   "--platform", PLATFORM_TAGS[platform], "--platform", COMPILED_PLATFORMS[platform]]
            print("+", " ".join(cmd))
            subprocess.run(cmd, check=True)
    for path in glob.glob(os.path.join(wheels_dir, "*.whl")):
        if os.path.basename(path).split("-")[0].lower() in EXCLUDED_DEPS:
            os.remove(path)
    wheels = sorted(os.path.basename(p) for p in glob.glob(os.path.join(wheels_dir, "*.whl")))
    chosen = [w for w in wheels if any(wheel_matches(w, PLATFORM_TAGS[p]) for p in platforms)]
    if not denoiser or not set(platforms) & set(DENOISER_PLATFORMS):
        chosen = [w for w in chosen if wheel_package(w) not in DENOISER_DEPS]
    if not compiled or not set(platforms) & set(COMPILED_PLATFORMS):
        chosen = [w for w in chosen if wheel_package(w) not in COMPILED_DEPS]
    needed = ("embreex", "openimageio") + (DENOISER_DEPS if denoiser and set(platforms) & set(DENOISER_PLATFORMS) else ())
    needed += COMPILED_DEPS if compiled and set(platforms) & set(COMPILED_PLATFORMS) else ()
    for pkg in needed:
        if not any(wheel_package(w) == pkg for w in chosen):
            raise SystemExit(f"error: no {pkg} wheel in {wheels_dir} for {platforms} "
                             "(run without --no-download)")
    return chosen


def wheel_package(name):
    """'OpenImageIO-3.0.21.0-cp311-....whl' -> 'openimageio'."""
    return os.path.basename(name).split("-")[0].lower()


def wheel_matches(name, pip_platform):
    tags = name[:-4].split("-")[-1].split(".")
    if "any" in tags:                       # pure Python (pycparser)
        return True
    if pip_platform.startswith("manylinux"):
        return any(t.startswith("manylinux") and t.endswith("x86_64") for t in tags)
    if pip_platform.startswith("macosx"):
        arch = pip_platform.rsplit("_", 1)[1] if "arm64" in pip_platform else "x86_64"
        return any(t.startswith("macosx") and t.endswith(arch) for t in tags) or "universal2" in name
    return pip_platform in tags


def check_tracer_imports():
    """The tracer is shipped as a sub-package: it must import itself relatively."""
    bad = []
    for path in glob.glob(os.path.join(REPO, "engine", "**", "*.py"), recursive=True):
        with open(path, encoding="utf-8") as fh:
            for n, line in enumerate(fh, 1):
                if re.match(r"\s*(from\s+engine[\s.]|import\s+engine\b)", line):
                    bad.append(f"{os.path.relpath(path, REPO)}:{n}: {line.strip()}")
    if bad:
        raise SystemExit("error: absolute imports of 'engine' break the bundled copy:\n  " + "\n  ".join(bad))


def manifest_text(wheels, platforms):
    with open(os.path.join(REPO, "blender_manifest.toml"), encoding="utf-8") as fh:
        text = fh.read()
    listed = re.findall(r'"\./wheels/([^"]+)"', text)
    if sorted(listed) != sorted(wheels):
        print(f"note: blender_manifest.toml lists {listed}; the build uses {wheels}")
    wheel_block = "wheels = [\n" + "".join(f'  "./wheels/{w}",\n' for w in wheels) + "]"
    text = re.sub(r"wheels = \[[^\]]*\]", wheel_block, text, count=1)
    text = re.sub(r"platforms = \[[^\]]*\]", "platforms = [" + ", ".join(f'"{p}"' for p in platforms) + "]",
                  text, count=1)
    return text


def stage(stage_dir, wheels, platforms, wheels_dir):
    shutil.copytree(os.path.join(REPO, "mcrt_addon"), stage_dir, ignore=IGNORE, dirs_exist_ok=True)
    shutil.copytree(os.path.join(REPO, "engine"), os.path.join(stage_dir, "tracer"), ignore=IGNORE)
    os.makedirs(os.path.join(stage_dir, "docs"), exist_ok=True)      # the preferences' Documentation button
    for page in glob.glob(os.path.join(REPO, "docs", "*.md")):
        shutil.copy2(page, os.path.join(stage_dir, "docs", os.path.basename(page)))
    os.makedirs(os.path.join(stage_dir, "wheels"), exist_ok=True)
    for w in wheels:
        shutil.copy2(os.path.join(wheels_dir, w), os.path.join(stage_dir, "wheels", w))
    with open(os.path.join(stage_dir, "blender_manifest.toml"), "w", encoding="utf-8") as fh:
        fh.write(manifest_text(wheels, platforms))


def version_of_manifest():
    with open(os.path.join(REPO, "blender_manifest.toml"), encoding="utf-8") as fh:
        return re.search(r'^version\s*=\s*"([^"]+)"', fh.read(), re.M).group(1)


def legacy_wheels(wheels_dir, offline, denoiser=True, compiled=True):
    """numpy, embreex, OpenImageIO (and the denoiser's pyoidn, cffi, pycparser, and numba with
    llvmlite) for CPython 3.11 on Linux x64, in wheels_dir/legacy/."""
    legacy_dir = os.path.join(wheels_dir, "legacy")
    os.makedirs(legacy_dir, exist_ok=True)
    if not offline:
        cmd = [sys.executable, "-m", "pip", "download", LEGACY_NUMPY, *PACKAGES, *(DENOISER if denoiser else ()),
               *(COMPILED if compiled else ()),
               "--dest", legacy_dir, "--only-binary=:all:", "--python-version", "3.11", "--implementation", "cp",
               "--quiet"]
        for tag in LEGACY_PLATFORMS:
            cmd += ["--platform", tag]
        print("+", " ".join(cmd))
        subprocess.run(cmd, check=True)
    found = {}
    for pkg in ("numpy", "embreex", "openimageio") + (DENOISER_DEPS if denoiser else ()) + (COMPILED_DEPS if compiled else ()):
        names = sorted(glob.glob(os.path.join(legacy_dir, f"{pkg}-*.whl")) +
                       glob.glob(os.path.join(legacy_dir, f"{pkg.replace('openimageio', 'OpenImageIO')}-*.whl")))
        if pkg == "numpy":
            names = [n for n in names if os.path.basename(n).startswith(LEGACY_NUMPY.replace("==", "-"))]
        if not names:
            raise SystemExit(f"error: no {pkg} wheel in {legacy_dir} (run without --no-download)")
        found[pkg] = names[-1]
    return found


def legacy_zip(stage_dir, path, vendor=None):
    """vendor: {"numpy": wheel, "embreex": wheel, ...}, unpacked into vendor/numpy and vendor/worker."""
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        for pkg, wheel in (vendor or {}).items():
            target = "numpy" if pkg == "numpy" else "worker"
            with zipfile.ZipFile(wheel) as whl:
                for info in whl.infolist():
                    if not info.is_dir():
                        zf.writestr(f"tncg15_mc/vendor/{target}/{info.filename}", whl.read(info),
                                    compresslevel=VENDOR_COMPRESSION)
        for root, _dirs, files in os.walk(stage_dir):
            rel_root = os.path.relpath(root, stage_dir)
            if rel_root.split(os.sep)[0] == "wheels":
                continue
            for f in files:
                if f == "blender_manifest.toml":
                    continue
                rel = os.path.normpath(os.path.join("tncg15_mc", rel_root, f))
                zf.write(os.path.join(root, f), rel)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--platform", nargs="+", default=["linux-x64"], choices=sorted(PLATFORM_TAGS))
    parser.add_argument("--no-download", action="store_true", help="use the wheels already in ./wheels/")
    parser.add_argument("--output-dir", default=os.path.join(REPO, "dist"))
    parser.add_argument("--wheels-dir", default=os.path.join(REPO, "wheels"))
    parser.add_argument("--no-denoiser", action="store_true",
                        help="leave out pyoidn (OIDN, about 88 MB a platform; bundled for linux-x64 and windows-x64)")
    parser.add_argument("--no-numba", action="store_true",
                        help="leave out numba and llvmlite (the compiled kernels, about 50 MB; bundled for linux-x64)")
    parser.add_argument("--with-denoiser", action="store_true", help=argparse.SUPPRESS)   # the default now
    args = parser.parse_args(argv)
    denoiser = not args.no_denoiser

    check_tracer_imports()
    compiled = not args.no_numba
    wheels = download_wheels(args.platform, args.wheels_dir, args.no_download, denoiser, compiled)
    blender_ext = find_blender_ext()
    if blender_ext is None:
        raise SystemExit("error: blender_ext.py not found (install the bpy wheel, or use "
                         "`blender --command extension build` from Blender 4.2+)")
    os.makedirs(args.output_dir, exist_ok=True)
    version = version_of_manifest()
    out_zip = os.path.join(args.output_dir, f"tncg15_mc-{version}.zip")
    with tempfile.TemporaryDirectory() as tmp:
        stage_dir = os.path.join(tmp, "tncg15_mc")
        stage(stage_dir, wheels, args.platform, args.wheels_dir)
        for cmd in ([sys.executable, blender_ext, "validate", stage_dir],
                    [sys.executable, blender_ext, "build", "--source-dir", stage_dir,
                     "--output-filepath", out_zip],
                    [sys.executable, blender_ext, "validate", out_zip]):
            print("+", " ".join(os.path.relpath(c, REPO) if c.startswith(REPO) else c for c in cmd))
            subprocess.run(cmd, check=True)
        legacy = os.path.join(args.output_dir, f"tncg15_mc-{version}-legacy.zip")
        legacy_zip(stage_dir, legacy, legacy_wheels(args.wheels_dir, args.no_download, denoiser, compiled))
    print(f"extension (Blender 4.2+): {out_zip} ({os.path.getsize(out_zip) / 1e6:.1f} MB)")
    print(f"legacy add-on (Blender 3.4): {legacy} ({os.path.getsize(legacy) / 1e6:.2f} MB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
