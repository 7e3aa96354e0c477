"""The spatial reference passes the spatial contract its engines are held to."""

from mechval.testing import SpatialContract


class TestReferenceSpatialContract(SpatialContract):
    engine = "reference"
