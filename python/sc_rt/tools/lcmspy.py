"""``sc-rt lcm-spy``: LCM's own graphical ``lcm-spy`` with our types.

lcm-spy decodes a message only when the Java class of its type is on the
CLASSPATH. This module builds that jar once from the ``.lcm`` files
(``lcm-gen --java``, ``javac`` against the lcm wheel's ``lcm.jar``, ``jar``),
caches it in ``$XDG_CACHE_HOME/sc-rt`` (default ``~/.cache/sc-rt``) under a
hash of the ``.lcm`` files and of ``lcm.jar``, and starts the wheel's real
``lcm-spy`` with it.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

from sc_rt.wire.lcmio import lcm_binary, lcm_prefix
from sc_rt.wire.codec import lcm_sources

__all__ = ["JavaMissing", "cache_dir", "types_jar", "spy_command"]

INSTALL_HINT = ("install a Java development kit (java, javac and jar): on Debian/Ubuntu "
                "`apt-get install default-jdk-headless`")


class JavaMissing(RuntimeError):
    pass


def cache_dir() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "sc-rt"


def lcm_jar() -> Path:
    p = lcm_prefix() / "share" / "java" / "lcm.jar"
    if not p.exists():
        raise FileNotFoundError(f"lcm.jar not found in the lcm wheel at {p}")
    return p


def _tools(*names: str) -> dict[str, str]:
    found = {n: shutil.which(n) for n in names}
    missing = [n for n, p in found.items() if p is None]
    if missing:
        raise JavaMissing(f"{', '.join(missing)} not found: {INSTALL_HINT}")
    return found  # type: ignore[return-value]


def _key(files: list[Path], jar: Path) -> str:
    h = hashlib.sha256()
    for f in files:
        h.update(f.name.encode() + b"\0" + f.read_bytes() + b"\0")
    h.update(jar.read_bytes())
    return h.hexdigest()[:16]


def types_jar(rebuild: bool = False, log=None) -> Path:
    """The jar of the sc_rt_lcm Java classes, built on first use and cached."""
    files, jar = lcm_sources(), lcm_jar()
    out = cache_dir() / f"sc_rt_lcm-{_key(files, jar)}.jar"
    if out.exists() and not rebuild:
        return out
    tools = _tools("javac", "jar")
    out.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="sc-rt-jar-") as tmp:
        src, classes = Path(tmp) / "src", Path(tmp) / "classes"
        src.mkdir()
        classes.mkdir()

        def run(cmd: list[str]) -> None:
            r = subprocess.run(cmd, capture_output=True, text=True)
            if r.returncode != 0:
                raise RuntimeError(f"{' '.join(cmd[:2])} ... failed ({r.returncode}):\n{r.stderr}{r.stdout}")

        if log:
            log(f"sc-rt lcm-spy: building the types jar {out} (once)")
        run([lcm_binary("lcm-gen"), "--java", "--jpath", str(src), *map(str, files)])
        java_files = sorted(str(p) for p in src.rglob("*.java"))
        if not java_files:
            raise RuntimeError("lcm-gen --java wrote no Java file")
        run([tools["javac"], "-nowarn", "-encoding", "UTF-8", "-cp", str(jar), "-d", str(classes),
             *java_files])
        part = out.with_suffix(f".{os.getpid()}.part")
        run([tools["jar"], "cf", str(part), "-C", str(classes), "."])
        os.replace(part, out)  # atomic: a concurrent first use sees a whole jar or none
    return out


def spy_command(url: str | None, title: str | None = None) -> tuple[list[str], dict[str, str]]:
    """The command and environment that start the wheel's lcm-spy with our
    types jar on its CLASSPATH."""
    _tools("java")
    jar = types_jar()
    env = dict(os.environ)
    env["CLASSPATH"] = str(jar) + (os.pathsep + env["CLASSPATH"] if env.get("CLASSPATH") else "")
    cmd = [lcm_binary("lcm-spy")]
    if url:
        cmd += ["--lcm-url", url]
    if title:
        cmd += ["--title", title]
    return cmd, env
