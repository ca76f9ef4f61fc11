"""Where the real recorded data of the tests lives: inside the repository (tests/data)."""

from pathlib import Path

DATA = Path(__file__).resolve().parent / "data"
NDI_PIVOT = DATA / "ndi-pivot"
