"""Geo-referencing of the mesh frame: local East-North-Up at a WGS84 origin, turned by a heading.

The mesh frame's origin (0, 0, 0) is at the geodetic `origin` (latitude, longitude in degrees,
altitude in metres); its +z is up (the ellipsoid normal there) and its +x points along the
bearing `heading_deg` (degrees clockwise from true north), so +y points 90 degrees to the left of
it. The conversions between the local East-North-Up frame and geodetic coordinates are
pymap3d's (WGS84 ellipsoid); only the turn by the heading, a rotation about up, is done here.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

ALTITUDE_REFS = ("amsl", "ellipsoid")
_NAMES = {
    "lat": "origin latitude",
    "lon": "origin longitude",
    "alt": "origin altitude",
    "heading_deg": "heading",
}


@dataclass(frozen=True)
class GeoFrame:
    """The mesh frame on the Earth. lat, lon: degrees (WGS84); alt: metres, above mean sea level
    (altitude_ref "amsl") or above the WGS84 ellipsoid ("ellipsoid"); heading_deg: the bearing of
    the mesh's +x axis. Raises ValueError naming a bad value."""

    lat: float
    lon: float
    alt: float
    heading_deg: float = 0.0
    altitude_ref: str = "amsl"

    def __post_init__(self):
        for name in ("lat", "lon", "alt", "heading_deg"):
            v = getattr(self, name)
            try:
                ok = math.isfinite(float(v))
            except (TypeError, ValueError):
                ok = False
            if not ok:
                what = _NAMES[name]
                raise ValueError(f"{what} must be a finite number, got {v!r}")
        if not -90.0 <= self.lat <= 90.0:
            raise ValueError(f"origin latitude must be within [-90, 90] degrees, got {self.lat}")
        if not -180.0 <= self.lon <= 180.0:
            raise ValueError(f"origin longitude must be within [-180, 180] degrees, got {self.lon}")
        if self.altitude_ref not in ALTITUDE_REFS:
            raise ValueError(
                f"altitude reference must be one of {', '.join(ALTITUDE_REFS)}, "
                f"got {self.altitude_ref!r}"
            )

    # -------------------------------------------------------------- mesh <-> ENU (a rotation)
    def _rot(self) -> np.ndarray:
        """R_enu_mesh (3, 3): mesh +x along the bearing heading_deg, z up."""
        h = math.radians(self.heading_deg)
        s, c = math.sin(h), math.cos(h)
        # columns: mesh +x -> (east, north) = (sin h, cos h); mesh +y -> 90 deg to its left
        return np.array([[s, -c, 0.0], [c, s, 0.0], [0.0, 0.0, 1.0]])

    def mesh_to_enu(self, xyz) -> np.ndarray:
        return np.asarray(xyz, float) @ self._rot().T

    def enu_to_mesh(self, enu) -> np.ndarray:
        return np.asarray(enu, float) @ self._rot()

    # -------------------------------------------------------------- geodetic (pymap3d)
    def to_geodetic(self, xyz):
        """(lat, lon, alt) arrays of mesh-frame points (N, 3); alt in the origin's reference."""
        import pymap3d

        enu = np.atleast_2d(self.mesh_to_enu(xyz))
        lat, lon, alt = pymap3d.enu2geodetic(
            enu[:, 0], enu[:, 1], enu[:, 2], self.lat, self.lon, self.alt
        )
        return np.asarray(lat, float), np.asarray(lon, float), np.asarray(alt, float)

    def to_mesh(self, lat, lon, alt) -> np.ndarray:
        """(N, 3) mesh-frame points of geodetic coordinates (the inverse of to_geodetic)."""
        import pymap3d

        e, n, u = pymap3d.geodetic2enu(
            np.asarray(lat, float),
            np.asarray(lon, float),
            np.asarray(alt, float),
            self.lat,
            self.lon,
            self.alt,
        )
        return self.enu_to_mesh(np.stack([np.ravel(e), np.ravel(n), np.ravel(u)], axis=1))

    def bearing(self, direction) -> float:
        """The compass bearing (degrees in [0, 360), clockwise from the origin's north) of a
        mesh-frame direction (3,), from its horizontal part."""
        e, n, _ = self.mesh_to_enu(np.asarray(direction, float))
        b = math.degrees(math.atan2(e, n)) % 360.0
        return 0.0 if b >= 360.0 else b  # -1e-15 % 360 rounds to 360

    def to_dict(self) -> dict:
        return {
            "latitude_deg": self.lat,
            "longitude_deg": self.lon,
            "altitude_m": self.alt,
            "altitude_reference": self.altitude_ref,
            "heading_deg": self.heading_deg,
        }
