"""openreloc-bench: object-level indoor camera relocalization benchmark and OpenReLoc reference."""

__version__ = "0.1.0"
