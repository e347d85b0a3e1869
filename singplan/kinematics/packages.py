"""Where a URDF's ``package://NAME/...`` files are, found as ROS would, without ROS.

A ``package://NAME/rel`` URI names the file ``rel`` inside the ROS package ``NAME``. ROS finds the
package on ``ROS_PACKAGE_PATH`` (ROS 1) or under ``share/`` of the ``AMENT_PREFIX_PATH`` prefixes
(ROS 2). A URDF handed around on its own usually sits inside its package (a folder holding
``package.xml``), and example-robot-data installs its packages under its own share folder. Pinocchio
resolves ``package://NAME/rel`` as ``<dir>/NAME/rel`` for each folder ``dir`` it is given, so the
folders returned here are *parents* of packages:

1. every folder above the URDF (a package folder named as the package, wherever it sits);
2. the folder above the nearest ``package.xml`` at or above the URDF, and that package under
   its own ``<name>`` when its folder is named otherwise (:func:`package_aliases`);
3. example-robot-data's ``share`` folder (its URDFs say ``package://example-robot-data/robots/...``);
4. the folders of ``ROS_PACKAGE_PATH`` (each a package or a folder of packages);
5. ``<prefix>/share`` of every ``AMENT_PREFIX_PATH`` prefix.

The same folders bound what a page may carry (:func:`mesh_roots`): a mesh or texture outside the
URDF's own folder tree and these packages is never read into an output.
"""

from __future__ import annotations

import os
import re
from functools import cache
from pathlib import Path

_PACKAGE_NAME = re.compile(r"<name>\s*([A-Za-z0-9_.-]+)\s*</name>")


def package_dirs(urdf_path: Path) -> tuple[Path, ...]:
    """The folders (parents of packages) that ``package://`` URIs of ``urdf_path`` resolve against, in order."""
    urdf = urdf_path.resolve()
    dirs: list[Path] = list(urdf.parents)
    home = package_home(urdf)
    if home is not None:
        dirs.append(home.parent)
    share = _example_robot_data_share()
    if share is not None:
        dirs.append(share)
    for entry in _env_paths("ROS_PACKAGE_PATH"):
        dirs += [entry, entry.parent]  # a package itself, or a folder of packages
    dirs += [prefix / "share" for prefix in _env_paths("AMENT_PREFIX_PATH")]
    return tuple(dict.fromkeys(d for d in dirs if d.is_dir()))


def package_home(urdf_path: Path) -> Path | None:
    """The package folder holding ``urdf_path`` (the nearest folder at or above it with a
    ``package.xml``), or None."""
    for folder in urdf_path.resolve().parents:
        if (folder / "package.xml").is_file():
            return folder
    return None


def package_aliases(urdf_path: Path) -> dict[str, Path]:
    """The URDF's own package by the ``<name>`` its package.xml gives, when that differs from the
    folder's name (a clone named ``ur_description-main`` still answers ``package://ur_description``)."""
    home = package_home(urdf_path)
    if home is None:
        return {}
    try:
        head = (home / "package.xml").read_bytes()[:65536].decode("utf-8", "replace")
    except OSError:
        return {}
    found = _PACKAGE_NAME.search(head)
    if found is None or found.group(1) == home.name:
        return {}
    return {found.group(1): home}


def resolve_uri(uri: str, urdf_path: Path) -> Path | None:
    """The file a mesh ``filename`` of ``urdf_path`` names (``package://``, ``file://``, absolute or
    relative to the URDF), or None when no folder holds it."""
    if uri.startswith("package://"):
        name, _, rel = uri[len("package://"):].partition("/")
        alias = package_aliases(urdf_path).get(name)
        candidates = [alias / rel] if alias is not None else []
        candidates += [d / name / rel for d in package_dirs(urdf_path)]
        return next((c for c in candidates if c.is_file()), None)
    path = Path(uri[len("file://"):] if uri.startswith("file://") else uri)
    path = path if path.is_absolute() else urdf_path.resolve().parent / path
    return path if path.is_file() else None


def mesh_roots(urdf_path: Path) -> tuple[Path, ...]:
    """The folders a URDF's meshes and their textures may come from: the URDF's own folder tree
    (its package when it is in one, else its folder) and the packages its ``package://`` URIs
    name that :func:`package_dirs` finds. Nothing outside them is read into an output."""
    urdf = urdf_path.resolve()
    home = package_home(urdf)
    roots = [home if home is not None else urdf.parent]
    roots += list(package_aliases(urdf).values())
    return tuple(dict.fromkeys(roots))


def package_root(uri: str, urdf_path: Path) -> Path | None:
    """The package folder a ``package://NAME/...`` URI resolves into (for :func:`mesh_roots` of a
    mesh found through it), or None."""
    if not uri.startswith("package://"):
        return None
    name = uri[len("package://"):].partition("/")[0]
    alias = package_aliases(urdf_path).get(name)
    if alias is not None:
        return alias
    return next((d / name for d in package_dirs(urdf_path) if (d / name).is_dir()), None)


def _env_paths(variable: str) -> list[Path]:
    return [Path(p) for p in os.environ.get(variable, "").split(os.pathsep) if p]


@cache
def _example_robot_data_share() -> Path | None:
    """example-robot-data's ``share`` folder (``share/example-robot-data/robots/...``), if installed."""
    try:
        import example_robot_data.robots_loader as loaders
    except ImportError:
        return None
    try:
        robots = Path(loaders.getModelPath("ur_description")).resolve()  # .../share/example-robot-data/robots
    except OSError:
        return None
    return robots.parent.parent
