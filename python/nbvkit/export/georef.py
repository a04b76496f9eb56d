"""Geo-referencing of the mesh frame: origin at a WGS84 point, +z up, +x along a heading.

The mesh frame's origin (0, 0, 0) is at the geodetic `origin` (latitude, longitude in degrees,
altitude in metres); its +z is up (the ellipsoid normal there) and its +x points along the
bearing `heading_deg` (degrees clockwise from true north), so +y points 90 degrees to the left of
it. The conversions between the local East-North-Up frame and geodetic coordinates are
pymap3d's (WGS84 ellipsoid); only the turn by the heading, a rotation about up, is done here.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

ALTITUDE_REFS = ("amsl", "ellipsoid")
#: |latitude| of the origin beyond which the export refuses (degrees). The local tangent plane
#: and the per-waypoint bearings stay exact near a pole, but north is undefined at the pole
#: itself and turns by 360 degrees round it: at 89.9 degrees the pole is 11.1 km from the
#: origin, farther than any site nbvkit plans (a waypoint there keeps a defined north).
MAX_ABS_LATITUDE = 89.9
#: the origin altitude's accepted range (m, either reference): below the Dead Sea shore
#: (-430 m) to above Everest (8849 m); the geoid departs from the ellipsoid by -106..+85 m.
ALTITUDE_RANGE = (-500.0, 10000.0)
#: the largest |heading| accepted (degrees): one full turn either way. A bearing is an angle of a
#: circle; a larger number is a typing error, and beyond about 1e16 degrees a float cannot even
#: hold its remainder modulo 360 (1e20 turned into 162 degrees instead of 280).
MAX_ABS_HEADING_DEG = 360.0
_NAMES = {
    "lat": "origin latitude",
    "lon": "origin longitude",
    "alt": "origin altitude",
    "heading_deg": "heading (--heading)",
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
        if abs(self.lat) > MAX_ABS_LATITUDE:
            raise ValueError(
                f"origin latitude {self.lat} is within {90 - abs(self.lat):.4g} degrees of a "
                f"pole: the export accepts |latitude| <= {MAX_ABS_LATITUDE} (north, and so every "
                "heading, is undefined at the pole and turns fully round it)"
            )
        if abs(self.heading_deg) > MAX_ABS_HEADING_DEG:
            raise ValueError(
                f"heading (--heading) must be within [-{MAX_ABS_HEADING_DEG:g}, "
                f"{MAX_ABS_HEADING_DEG:g}] degrees (the bearing of the mesh's +x axis), "
                f"got {self.heading_deg!r}"
            )
        lo, hi = ALTITUDE_RANGE
        if not lo <= self.alt <= hi:
            raise ValueError(
                f"origin altitude must be within [{lo:g}, {hi:g}] m ({self.altitude_ref}), "
                f"got {self.alt}"
            )
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
        return self.local_bearing(direction, self.lat, self.lon)

    def local_enu(self, direction, lat: float, lon: float) -> np.ndarray:
        """A mesh-frame direction (3,) in the East-North-Up frame at (lat, lon) (degrees): the
        local north and up there, not the origin's (they differ by the meridians' convergence,
        a large angle near a pole)."""
        from pymap3d.ecef import enu2uvw, uvw2enu

        e, n, u = self.mesh_to_enu(np.asarray(direction, float))
        return np.array(uvw2enu(*enu2uvw(e, n, u, self.lat, self.lon), lat, lon), float)

    def local_bearing(self, direction, lat: float, lon: float) -> float:
        """The compass bearing (degrees in [0, 360), clockwise from the local north at (lat,
        lon)) of a mesh-frame direction (3,), from its horizontal part."""
        e, n, _ = self.local_enu(direction, lat, lon)
        b = math.degrees(math.atan2(e, n)) % 360.0
        return 0.0 if b >= 360.0 else b  # -1e-15 % 360 rounds to 360

    def ellipsoid_height(self, alt) -> np.ndarray:
        """Heights above the WGS84 ellipsoid (m) of points with altitudes `alt` (to_geodetic's,
        in the origin's reference): the same with an ellipsoidal origin; with an AMSL origin,
        alt + the EGM96 geoid height **at the origin** (geoid_height_at_origin). One constant
        for every point: to_geodetic places the points from the origin's height, so this is the
        ellipsoidal height of the same points, and differences of heights (the files' relative
        altitudes) are the same in both references. ValueError when the geoid is not at hand."""
        alt = np.asarray(alt, float)
        if self.altitude_ref == "ellipsoid":
            return alt.copy()
        return alt + self.geoid_height_at_origin()

    def geoid_height_at_origin(self) -> float:
        """The EGM96 geoid's height above the WGS84 ellipsoid at the origin (m; egm96_geoid_height:
        ValueError without pyproj and PROJ's grid)."""
        return float(egm96_geoid_height([self.lat], [self.lon])[0])

    def to_dict(self) -> dict:
        return {
            "latitude_deg": self.lat,
            "longitude_deg": self.lon,
            "altitude_m": self.alt,
            "altitude_reference": self.altitude_ref,
            "heading_deg": self.heading_deg,
        }


@functools.lru_cache(maxsize=1)
def _egm96_transformer(pyproj):
    """EGM96 heights to WGS84 ellipsoidal ones, built and checked once a process."""
    t = pyproj.Transformer.from_crs("EPSG:4326+5773", "EPSG:4979", always_xy=True)
    _, _, n0 = t.transform(0.0, 0.0, 0.0)
    if not abs(n0 - 17.16) < 0.1:
        raise ValueError(
            "PROJ applies no EGM96 geoid (its egm96_15.gtx grid is missing: Debian proj-data); "
            "give the origin's height above the ellipsoid with --altitude-ref ellipsoid"
        )
    return t


def egm96_geoid_height(lat, lon) -> np.ndarray:
    """The EGM96 geoid's height above the WGS84 ellipsoid (m) at (lat, lon) (degrees), from
    PROJ's egm96_15.gtx grid through pyproj. ValueError naming what is missing when pyproj or
    the grid is not installed (PROJ would then silently apply no geoid at all: checked against
    the grid's value at (0, 0), +17.16 m)."""
    try:
        import pyproj
    except ImportError:
        raise ValueError(
            "heights above the ellipsoid from an AMSL origin need the EGM96 geoid: install "
            "pyproj with PROJ's egm96_15.gtx grid (Debian python3-pyproj and proj-data), or give "
            "the origin's height above the ellipsoid with --altitude-ref ellipsoid"
        ) from None
    t = _egm96_transformer(pyproj)
    lat = np.asarray(lat, float)
    lon = np.asarray(lon, float)
    _, _, h = t.transform(lon, lat, np.zeros_like(lat))
    return np.asarray(h, float)
