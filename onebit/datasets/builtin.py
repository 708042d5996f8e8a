"""Built-in sites shipped with onebit: ``building`` (Bobadilla Fig. 1), ``lab`` (Fig. 8), ``hallway`` (FindingHuMo)."""

from __future__ import annotations

from pathlib import Path

from onebit.core.errors import SiteError
from onebit.core.site import Site, load_site

# --------------------------------------------------------------------------- built-in sites

BUILTIN_DIR = Path(__file__).with_name("sites")


def builtin_site_path(name: str) -> Path:
    """Path of a built-in site file (``building`` = paper Fig. 1, ``lab`` = paper Fig. 8)."""
    p = BUILTIN_DIR / f"{name}.toml"
    if not p.exists():
        known = sorted(q.stem for q in BUILTIN_DIR.glob("*.toml"))
        raise SiteError(f"no built-in site {name!r}; known: {known}")
    return p


def builtin_site(name: str) -> Site:
    return load_site(builtin_site_path(name))
