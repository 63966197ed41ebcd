"""Run the Khronos glTF-Validator (npm package ``gltf-validator``) on a glTF/GLB file.

The validator is JavaScript (compiled from Dart), so this module runs Node.js on
``tools/gltf_validate.mjs`` (in the repository) and parses the report it prints::

    from lopcook.verify.gltf_validator import validate, problems
    report = validate("preview.glb")
    report["issues"]["numErrors"], report["issues"]["numWarnings"]
    problems(report)          # ["ERROR ACCESSOR_MIN_MISMATCH /accessors/0/min/1: ...", ...]

Where things are found
----------------------
* node: ``$LOPCOOK_NODE``, else ``node`` on ``PATH``.
* the package folder: ``$GLTF_VALIDATOR_DIR``, else ``<repo>/.ci/node/node_modules/gltf-validator``
  (what ``.ci/run`` installs, pinned to ``PINNED_VERSION``; by hand:
  ``npm install --prefix .ci/node gltf-validator@2.0.0-dev.3.10 --no-audit --no-fund``).
* the script: ``<repo>/tools/gltf_validate.mjs``.

When any of them is missing, ``validate`` raises ``GltfValidatorUnavailable`` naming what is
missing and how to install it; ``available()`` says whether it would work.

Severities in the report: 0 error, 1 warning, 2 info, 3 hint.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path

#: The gltf-validator version .ci/run installs (the newest on npm when this was written).
PINNED_VERSION = "2.0.0-dev.3.10"

REPO = Path(__file__).resolve().parents[2]
SCRIPT = REPO / "tools" / "gltf_validate.mjs"
DEFAULT_PACKAGE = REPO / ".ci" / "node" / "node_modules" / "gltf-validator"
SEVERITY = {0: "ERROR", 1: "WARNING", 2: "INFO", 3: "HINT"}
INSTALL_HINT = (f"install it with `npm install --prefix .ci/node gltf-validator@{PINNED_VERSION} "
                "--no-audit --no-fund` in the repository root (needs Node.js and npm), "
                "or set GLTF_VALIDATOR_DIR to an installed package folder")


class GltfValidatorUnavailable(RuntimeError):
    """Node.js, the gltf-validator package or tools/gltf_validate.mjs cannot be found."""


class GltfValidatorFailed(RuntimeError):
    """The validator ran but produced no report (crash, timeout, unparsable output)."""


def _node() -> str | None:
    return os.environ.get("LOPCOOK_NODE") or shutil.which("node")


def _package_dir() -> Path:
    env = os.environ.get("GLTF_VALIDATOR_DIR")
    return Path(env) if env else DEFAULT_PACKAGE


def locate() -> tuple[str, Path, Path]:
    """``(node, package_dir, script)``; raises GltfValidatorUnavailable if one is missing."""
    node = _node()
    if not node:
        raise GltfValidatorUnavailable("glTF validator unavailable: Node.js (`node`) not found on PATH "
                                       "(or set LOPCOOK_NODE); " + INSTALL_HINT)
    package = _package_dir()
    if not (package / "package.json").is_file():
        raise GltfValidatorUnavailable(f"glTF validator unavailable: npm package gltf-validator not found at "
                                       f"{package}; " + INSTALL_HINT)
    if not SCRIPT.is_file():
        raise GltfValidatorUnavailable(f"glTF validator unavailable: {SCRIPT} not found "
                                       "(it lives in the repository's tools/ folder)")
    return node, package, SCRIPT


def available() -> bool:
    """True when ``validate`` can run (node, package and script found)."""
    try:
        locate()
    except GltfValidatorUnavailable:
        return False
    return True


def version() -> str:
    """The installed gltf-validator package version (from its package.json)."""
    _, package, _ = locate()
    return json.loads((package / "package.json").read_text(encoding="utf-8"))["version"]


def validate(path, *, timeout: float = 300.0) -> dict:
    """Validate one ``.gltf`` (external resources read from its folder) or ``.glb`` file.

    Returns the validator's report (a dict: ``uri``, ``mimeType``, ``validatorVersion``,
    ``issues`` with ``numErrors``/``numWarnings``/``numInfos``/``numHints``/``messages``, ``info``;
    no timestamp). A report with errors is returned, not raised; see ``problems``.

    Raises GltfValidatorUnavailable (see the module docstring), FileNotFoundError for a missing
    ``path``, GltfValidatorFailed when the validator gives no report (e.g. unreadable bytes).
    """
    node, package, script = locate()
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such file")
    env = dict(os.environ, GLTF_VALIDATOR_DIR=str(package))
    try:
        proc = subprocess.run([node, str(script), str(path.resolve())], capture_output=True, text=True,
                              timeout=timeout, env=env, check=False)
    except subprocess.TimeoutExpired:
        raise GltfValidatorFailed(f"{path}: glTF validator timed out after {timeout:g} s") from None
    if proc.returncode not in (0, 1):
        raise GltfValidatorFailed(f"{path}: glTF validator exited {proc.returncode}: {proc.stderr.strip()}")
    try:
        (report,) = json.loads(proc.stdout)
    except (ValueError, TypeError) as exc:
        raise GltfValidatorFailed(f"{path}: cannot parse the validator output ({exc}): "
                                  f"{proc.stdout[:200]!r} {proc.stderr.strip()[:200]!r}") from None
    if "fatal" in report:
        raise GltfValidatorFailed(f"{path}: glTF validator could not validate the file: {report['fatal']}")
    return report


def problems(report: dict, max_severity: int = 1) -> list[str]:
    """Messages of ``report`` with severity <= ``max_severity`` (default: errors and warnings),
    each as ``"SEVERITY CODE POINTER: message"``."""
    out = []
    for m in report.get("issues", {}).get("messages", []):
        if m.get("severity", 0) <= max_severity:
            where = m.get("pointer") or (f"offset {m['offset']}" if "offset" in m else "")
            out.append(f"{SEVERITY.get(m.get('severity'), m.get('severity'))} {m.get('code')} {where}: "
                       f"{m.get('message')}".replace("  ", " "))
    return out


__all__ = ["validate", "available", "version", "locate", "problems", "PINNED_VERSION",
           "GltfValidatorUnavailable", "GltfValidatorFailed"]
