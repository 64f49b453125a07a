"""Gauss-point material laws for granular materials: the microplane CPA model and reference laws.

Public names: ``CPAModel``, ``CPAParameters``, ``load_preset``, ``load_parameters``,
``LinearElastic``, ``VonMises``, and the modules ``planes``, ``anisotropy``, ``failure``, ``driver``.
"""

from material.parameters import CPAParameters, load_parameters, load_preset, save_parameters
from material import anisotropy, base
from material.elastic import LinearElastic
from material.cpa import CPAModel
from material.plasticity import DruckerPrager, GradientVonMises, MohrCoulomb, VonMises
from material import driver

__all__ = [
    "CPAParameters",
    "load_parameters",
    "load_preset",
    "save_parameters",
    "anisotropy",
    "base",
    "LinearElastic",
    "CPAModel",
    "driver",
    "VonMises",
    "GradientVonMises",
    "DruckerPrager",
    "MohrCoulomb",
]
