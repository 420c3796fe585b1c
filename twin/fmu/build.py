"""Compile the generic FMU runtime once per platform and cache the shared library.

The runtime (``twin/fmu/c/twin_lti.c``) does not depend on the model, so the
binary is built the first time an FMU is exported on a machine and reused
afterwards: re-exporting after a parameter change needs no compiler.
The cache lives in ``$TWIN_CACHE_DIR`` or ``~/.cache/twin``.
"""

from __future__ import annotations

import hashlib
import logging
import os
import platform
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from twin.errors import TwinError

log = logging.getLogger(__name__)

MODEL_IDENTIFIER = "twin_lti"


class FMUBuildError(TwinError):
    """No C compiler was found, or compiling the FMU runtime failed."""


#: The runtime's C files: the translation unit (first) and the files it includes.
RUNTIME_FILES = (f"{MODEL_IDENTIFIER}.c", "twin_core.c", "twin_fmi2.c", "twin_fmi3.c")


def runtime_source() -> Path:
    """Path of the C source of the FMU runtime shipped with the package (the translation unit; it includes
    the other :data:`RUNTIME_FILES` from its folder)."""
    return Path(str(resources.files("twin.fmu") / "c" / f"{MODEL_IDENTIFIER}.c"))


def runtime_sources() -> dict[str, bytes]:
    """Every C file of the runtime by name, as an FMU's ``sources/`` ships them."""
    folder = runtime_source().parent
    return {name: (folder / name).read_bytes() for name in RUNTIME_FILES}


def fmi_headers_dir() -> Path:
    """Folder with the FMI 2.0 headers (shipped by FMPy in ``fmpy/c-code``)."""
    import fmpy

    path = Path(fmpy.__file__).parent / "c-code"
    if not (path / "fmi2Functions.h").is_file():
        raise FMUBuildError(f"FMI 2.0 headers not found in {path}: reinstall fmpy")
    return path


#: FMPy's copy of fmi2Functions.h always names the functions without a prefix; the standard's definition
#: (FMI 2.0.x) pastes ``FMI2_FUNCTION_PREFIX`` in front when it is defined, so that FMUs compiled from
#: source can be linked statically side by side.
_UNPREFIXED = "#define fmi2FullName(name) name\n"
_PREFIXED = """#if defined(FMI2_FUNCTION_PREFIX)
  #define fmi2Paste(a,b)     a ## b
  #define fmi2PasteB(a,b)    fmi2Paste(a,b)
  #define fmi2FullName(name) fmi2PasteB(FMI2_FUNCTION_PREFIX, name)
#else
  #define fmi2FullName(name) name
#endif
"""
FMI2_HEADERS = ("fmi2Functions.h", "fmi2FunctionTypes.h", "fmi2TypesPlatform.h")
FMI3_HEADERS = ("fmi3Functions.h", "fmi3FunctionTypes.h", "fmi3PlatformTypes.h")


def fmi2_headers() -> dict[str, bytes]:
    """The FMI 2.0 headers the runtime is compiled with and an FMU's ``sources/`` ship, by file name:
    FMPy's, with the function prefix of the standard (``-DFMI2_FUNCTION_PREFIX=<modelIdentifier>_``)."""
    folder = fmi_headers_dir()
    out = {name: (folder / name).read_bytes() for name in FMI2_HEADERS}
    text = out["fmi2Functions.h"].decode("latin-1").replace("\r\n", "\n")
    if _UNPREFIXED not in text and "FMI2_FUNCTION_PREFIX)" not in text:
        raise FMUBuildError(f"{folder / 'fmi2Functions.h'}: no definition of fmi2FullName found: reinstall fmpy")
    out["fmi2Functions.h"] = text.replace(_UNPREFIXED, _PREFIXED, 1).encode("latin-1")
    return out


def fmi_headers() -> dict[str, bytes]:
    """The FMI 2.0 headers (:func:`fmi2_headers`) and FMPy's copies of the standard FMI 3.0 headers (which
    honour ``FMI3_FUNCTION_PREFIX`` as they are), by file name."""
    folder = fmi_headers_dir()
    missing = [name for name in FMI3_HEADERS if not (folder / name).is_file()]
    if missing:
        raise FMUBuildError(f"FMI 3.0 headers {', '.join(missing)} not found in {folder}: reinstall fmpy")
    return {**fmi2_headers(), **{name: (folder / name).read_bytes() for name in FMI3_HEADERS}}


def platform_folder() -> str:
    """FMI 2.0 binaries folder name for this machine, e.g. ``linux64``."""
    bits = "64" if sys.maxsize > 2**32 else "32"
    system = {"Linux": "linux", "Darwin": "darwin", "Windows": "win"}.get(platform.system())
    if system is None:
        raise FMUBuildError(f"no FMI 2.0 platform name for {platform.system()}")
    return system + bits


def platform_tuple() -> str:
    """FMI 3.0 binaries folder name for this machine, e.g. ``x86_64-linux``."""
    system = {"Linux": "linux", "Darwin": "darwin", "Windows": "windows"}.get(platform.system())
    machine = {
        "amd64": "x86_64",
        "x86_64": "x86_64",
        "arm64": "aarch64",
        "aarch64": "aarch64",
        "i386": "x86",
        "i686": "x86",
        "x86": "x86",
    }.get(platform.machine().lower())
    if system is None or machine is None:
        raise FMUBuildError(f"no FMI 3.0 platform tuple for {platform.machine()} {platform.system()}")
    return f"{machine}-{system}"


def shared_library_suffix() -> str:
    """``.so``, ``.dylib`` or ``.dll``."""
    return {"linux": ".so", "darwin": ".dylib", "win": ".dll"}[platform_folder()[:-2]]


def find_compiler() -> str:
    """The C compiler to use: ``$CC``, else ``cc``, ``gcc`` or ``clang`` on the PATH."""
    candidates = [os.environ["CC"]] if os.environ.get("CC") else ["cc", "gcc", "clang"]
    for name in candidates:
        path = shutil.which(name)
        if path:
            return path
    raise FMUBuildError(
        f"no C compiler found (looked for {', '.join(candidates)}); install one, e.g. 'apt-get install gcc', "
        "or set CC to its path. It is needed once per machine to build the FMU runtime."
    )


def cache_dir() -> Path:
    """Where compiled runtimes are kept."""
    return Path(os.environ.get("TWIN_CACHE_DIR", Path.home() / ".cache" / "twin"))


@dataclass(frozen=True)
class CrossTarget:
    """A platform the runtime is cross-compiled for: its FMI 2.0 folder, FMI 3.0 folder, library suffix and
    the compiler that builds for it (found on the PATH, e.g. Debian's gcc-mingw-w64-x86-64)."""

    fmi2_folder: str
    fmi3_folder: str
    suffix: str
    compiler: str


CROSS_TARGETS = (CrossTarget("win64", "x86_64-windows", ".dll", "x86_64-w64-mingw32-gcc"),)


def available_cross_targets() -> list[CrossTarget]:
    """The cross targets other than this machine's own platform whose compiler is on the PATH."""
    native = platform_folder()
    return [t for t in CROSS_TARGETS if t.fmi2_folder != native and shutil.which(t.compiler)]


def compiled_runtime(rebuild: bool = False, target: CrossTarget | None = None) -> Path:
    """Path of the compiled runtime for this platform (or a cross ``target``), compiling it if needed.

    Raises
    ------
    FMUBuildError
        No compiler, or the compiler failed (its own message is included).
    """
    extra = b"".join(text for name, text in runtime_sources().items() if name != runtime_source().name)
    return _compiled(runtime_source(), fmi_headers(), MODEL_IDENTIFIER, "the FMU runtime", rebuild, extra, target)


def compiled_recorder(rebuild: bool = False) -> Path:
    """Path of the compiled recording loop of :mod:`twin.fmu.run` (``c/record.c``), compiling it if needed."""
    source = Path(str(resources.files("twin.fmu") / "c" / "record.c"))
    return _compiled(source, {}, "twin_record", "the FMU recording loop", rebuild)


def _compiled(
    source: Path,
    headers: dict[str, bytes],
    name: str,
    what: str,
    rebuild: bool,
    included: bytes = b"",
    cross: CrossTarget | None = None,
) -> Path:
    digest = hashlib.sha256(source.read_bytes() + included + b"".join(headers.values())).hexdigest()[:16]
    folder, suffix = (
        (platform_folder(), shared_library_suffix()) if cross is None else (cross.fmi2_folder, cross.suffix)
    )
    target = cache_dir() / f"{folder}-{digest}" / (name + suffix)
    if target.is_file() and not rebuild:
        return target
    if cross is None:
        compiler = find_compiler()
    elif not (compiler := shutil.which(cross.compiler)):
        raise FMUBuildError(f"no {cross.compiler} on the PATH to build the {cross.fmi2_folder} binary")
    target.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=target.parent) as tmp:
        out = Path(tmp) / target.name
        for header, text in headers.items():
            (Path(tmp) / header).write_bytes(text)
        pic = ["-fPIC"] if cross is None else ["-static-libgcc"]  # a DLL is position-independent already
        cmd = [compiler, "-shared", *pic, "-O2", "-o", str(out), str(source), f"-I{tmp}", "-lm"]
        log.info("compiling %s: %s", what, " ".join(cmd))
        try:
            proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
        except OSError as exc:
            raise FMUBuildError(f"could not run the C compiler {compiler}: {exc}") from None
        if proc.returncode != 0:
            raise FMUBuildError(f"compiling {what} with {compiler} failed:\n{proc.stderr.strip()}")
        os.replace(out, target)  # atomic: a concurrent build never sees half a library
    return target
