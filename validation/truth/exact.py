"""The exact D_LL(r) a flow's statistics are compared with, and its reference computed
apart from the simulator's code (:mod:`validation.truth.independent`).

Kinematic simulation: the isotropic integral of its continuous spectrum. A DNS: the
direction-averaged sum over the modes of its snapshots, grouped by |k| (docs/dns.md §9).
"""

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from simulator.dns.field_statistics import modal_dll
from simulator.spectra import Spectrum
from simulator.truth import longitudinal_structure_function
from validation.truth import independent


class ExactStructure(Protocol):
    """The exact longitudinal structure function of a flow."""

    def dll(self, r: np.ndarray) -> np.ndarray:
        """D_LL(r), m²/s², by the simulator's own code."""
        ...

    def reference(self, r: np.ndarray) -> np.ndarray:
        """The same D_LL(r) computed apart from the simulator's code, m²/s²."""
        ...


@dataclass(frozen=True)
class SpectrumStructure:
    """A KS flow's exact D_LL: its continuous spectrum."""

    spectrum: Spectrum

    def dll(self, r: np.ndarray) -> np.ndarray:
        return longitudinal_structure_function(self.spectrum, r)

    def reference(self, r: np.ndarray) -> np.ndarray:
        return independent.exact_dll(self.spectrum, r)


@dataclass(frozen=True)
class ModalStructure:
    """A DNS's exact D_LL: the energies of its modes by |k|, averaged over its snapshots.

    Attributes
    ----------
    k : ndarray, shape (S,)
        The distinct |k|, 1/m.
    energy : ndarray, shape (S,)
        Mean kinetic energy of the modes of each |k|, m²/s².
    """

    k: np.ndarray
    energy: np.ndarray

    def dll(self, r: np.ndarray) -> np.ndarray:
        return modal_dll(self.k, self.energy, r)

    def reference(self, r: np.ndarray) -> np.ndarray:
        return independent.modal_dll(self.k, self.energy, r)
