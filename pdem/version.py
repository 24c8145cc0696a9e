"""The version of pdem (written into every results file and checkpoint)."""
__version__ = "0.2.0"
