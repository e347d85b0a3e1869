"""Where a URDF's mesh and texture files are, found as ROS would without ROS, and which may be read.

A ``package://NAME/rel`` URI names the file ``rel`` inside the ROS package ``NAME``. ROS finds the
package on ``ROS_PACKAGE_PATH`` (ROS 1) or under ``share/`` of the ``AMENT_PREFIX_PATH`` prefixes
(ROS 2). A URDF handed around on its own usually sits inside its package (a folder holding
``package.xml``), and example-robot-data installs its packages under its own share folder. The
folders searched for ``NAME`` (:func:`package_dirs`, parents of packages, in this order):

1. every folder above the URDF (a package folder named as the package, wherever it sits);
2. the folder above the nearest ``package.xml`` at or above the URDF, and that package under
   its own ``<name>`` when its folder is named otherwise (:func:`package_aliases`);
3. example-robot-data's ``share`` folder (its URDFs say ``package://example-robot-data/robots/...``);
4. the folders of ``ROS_PACKAGE_PATH`` (each a package or a folder of packages);
5. ``<prefix>/share`` of every ``AMENT_PREFIX_PATH`` prefix.

A folder ``<dir>/NAME`` found there is the package only when it is one: it holds a
``package.xml``, or it lies inside the URDF's own folder tree (:func:`own_tree`). So
``package://etc/passwd`` is no package (``/etc`` holds no ``package.xml``), while a description
copied without its ``package.xml`` still finds its meshes next to its ``urdf`` folder.

What may be read into an output (:func:`locate_mesh`, :func:`texture_allowed`): a file named by
``package://`` only from inside that package, any other file (relative, absolute, ``file://``)
only from inside the URDF's own folder tree, and a mesh's texture only from inside the folder its
mesh may come from or the URDF's own tree; symbolic links are followed before the check, so a
link inside a package that points outside it is outside. Anything else is left out of the page
with a warning (:mod:`singplan.outputs.scene`).
"""

from __future__ import annotations

import os
import re
from functools import cache
from pathlib import Path
from typing import NamedTuple

from singplan.kinematics.files import is_within

PACKAGE_SEARCH = ("looked in the URDF's own package, the folders above it, example-robot-data, ROS_PACKAGE_PATH "
                  "and AMENT_PREFIX_PATH; a package is a folder holding package.xml")
_PACKAGE_NAME = re.compile(r"<name>\s*([A-Za-z0-9_.-]+)\s*</name>")
# <package>/urdf/arm.urdf (ROS), <package>/robots/arm.urdf (example-robot-data)
_DESCRIPTION_FOLDERS = ("urdf", "robots")


def package_dirs(urdf_path: Path) -> tuple[Path, ...]:
    """The folders (parents of packages) that ``package://`` URIs of ``urdf_path`` are looked up in, in order."""
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


def own_tree(urdf_path: Path) -> Path:
    """The URDF's own folder tree: its package (:func:`package_home`); without one, its folder, or
    the folder above when that is named ``urdf`` or ``robots`` (a description's usual layout)."""
    home = package_home(urdf_path)
    if home is not None:
        return home
    folder = urdf_path.resolve().parent
    return folder.parent if folder.name in _DESCRIPTION_FOLDERS else folder


def package_aliases(urdf_path: Path) -> dict[str, Path]:
    """The URDF's own package by the ``<name>`` its package.xml gives, when that differs from the
    folder's name (a clone named ``ur_description-main`` still answers ``package://ur_description``)."""
    home = package_home(urdf_path)
    if home is None:
        return {}
    try:
        with (home / "package.xml").open("rb") as f:  # a regular file (package_home checked); its head names it
            head = f.read(65536).decode("utf-8", "replace")
    except OSError:
        return {}
    found = _PACKAGE_NAME.search(head)
    if found is None or found.group(1) == home.name:
        return {}
    return {found.group(1): home}


def find_package(name: str, urdf_path: Path) -> Path | None:
    """The folder of package ``name`` for ``urdf_path``'s URIs (see the module's docstring), or None."""
    if not name or name in (".", "..") or "/" in name or "\\" in name:
        return None
    alias = package_aliases(urdf_path).get(name)
    if alias is not None:
        return alias
    tree = own_tree(urdf_path)
    for d in package_dirs(urdf_path):
        folder = d / name
        if folder.is_dir() and ((folder / "package.xml").is_file() or is_within(folder, (tree,))):
            return folder
    return None


class MeshFile(NamedTuple):
    """Where a mesh URI of a URDF leads.

    Attributes:
        uri: the ``filename`` as the URDF gives it.
        path: the file it names (not yet checked to exist), None when no package holds it.
        root: the folder it must lie inside to be read (its package, or the URDF's own tree).
    """

    uri: str
    path: Path | None
    root: Path

    @property
    def allowed(self) -> bool:
        """The file lies inside its root (symbolic links followed on both sides)."""
        return self.path is not None and is_within(self.path, (self.root,))


def locate_mesh(uri: str, urdf_path: Path) -> MeshFile:
    """The file a mesh ``filename`` of ``urdf_path`` names (``package://``, ``file://``, absolute or
    relative to the URDF) and the folder it must stay inside."""
    if uri.startswith("package://"):
        name, _, rel = uri[len("package://"):].partition("/")
        package = find_package(name, urdf_path)
        if package is None:
            return MeshFile(uri, None, own_tree(urdf_path))
        return MeshFile(uri, package / rel, package)
    path = Path(uri[len("file://"):] if uri.startswith("file://") else uri)
    return MeshFile(uri, path if path.is_absolute() else urdf_path.resolve().parent / path, own_tree(urdf_path))


def texture_allowed(image: Path, mesh: MeshFile, urdf_path: Path) -> bool:
    """A mesh's texture may be read: it lies inside the mesh's root or the URDF's own tree."""
    return is_within(image, (mesh.root, own_tree(urdf_path)))


def resolve_uri(uri: str, urdf_path: Path) -> Path | None:
    """The existing file a mesh ``filename`` of ``urdf_path`` names, or None (no package holds it,
    or no such file). Whether it may be read is :attr:`MeshFile.allowed` of :func:`locate_mesh`."""
    found = locate_mesh(uri, urdf_path).path
    return found if found is not None and found.is_file() else None


def mesh_roots(urdf_path: Path) -> tuple[Path, ...]:
    """The folders a URDF's relative and absolute mesh paths may lie in: its own tree (and its
    package under its ``<name>``); ``package://`` files lie in their package (:func:`package_root`)."""
    roots = [own_tree(urdf_path), *package_aliases(urdf_path).values()]
    return tuple(dict.fromkeys(roots))


def package_root(uri: str, urdf_path: Path) -> Path | None:
    """The package folder a ``package://NAME/...`` URI resolves into, or None."""
    if not uri.startswith("package://"):
        return None
    return find_package(uri[len("package://"):].partition("/")[0], urdf_path)


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
