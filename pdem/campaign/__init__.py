"""Campaigns: many runs of one base scene (seeds, parameter grids, explicit cases).

A campaign file (`pdem.campaign.spec`) expands into one directory per member with its resolved
scene and a manifest (`pdem.campaign.layout`, in the format of `pdem.format.campaign`); the
members run here, several at once (`pdem.campaign.local`), or as a SLURM job array
(`pdem.campaign.slurm`), each through the ``pdem run`` command line (`pdem.campaign.member`),
which resumes a stopped member from its checkpoint; `pdem.campaign.status` reports where every
member is. Nothing here imports the engine except `pdem.campaign.validate.check_member`. See docs/campaigns.md.
"""
from .cli import main

__all__ = ["main"]
