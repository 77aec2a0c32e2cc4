"""Ferraris' calibration (Ferraris, Grimaldi & Parvis 1995, as imucal implements it): six faces and three turns.

:mod:`~optcal.families.ferraris.regions` takes the nine stretches (imucal's section list, a ``part``
column, or found in the recording); :mod:`~optcal.families.ferraris.method` applies the equations
and gives their statistics.
"""

from optcal.families.ferraris.method import FerrarisFit, ferraris_fit
from optcal.families.ferraris.regions import (FerrarisRegions, find_regions, regions_for, regions_from_labels,
                                              regions_from_section_list)

__all__ = ["FerrarisFit", "FerrarisRegions", "ferraris_fit", "find_regions", "regions_for",
           "regions_from_labels", "regions_from_section_list"]
