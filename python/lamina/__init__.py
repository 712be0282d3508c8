"""lamina: layered BRDF models for rendering research.

Evaluate f(wi, wo) of a layer stack on NumPy arrays:

    >>> import numpy as np, lamina
    >>> stack = lamina.Stack([lamina.materials.metal("Au", roughness=0.2)])
    >>> f = stack.eval(np.array([0.0, 0.0, 1.0]), np.array([0.3, 0.0, 0.95]))  # (3,) linear RGB, 1/sr

Conventions (local frame, z = normal, directions pointing away, f without the cosine): docs/conventions.md.
"""

from . import atlas, dask, family, materials, measured, mitsuba, oat, optics, plot, reference
from ._lamina import __version__
from .catalogue import MODELS, models
from .choose import Choice, choose
from .fit import FitResult, ModelFits, fit, fit_models
from .layers import Conductor, Dielectric, Diffuse, Param
from .optics import jacobian_reflect, jacobian_refract
from .pictures import gallery
from .renderer import DirectionalLight, EnvironmentLight, Mesh, PointLight, read_image, render, save_image, sky
from .spectrum import RGB_WAVELENGTHS, Spectrum, to_srgb, to_xyz, xyz_weights
from .stack import Stack

__all__ = [
    "MODELS",
    "models",
    "choose",
    "Choice",
    "fit",
    "fit_models",
    "FitResult",
    "ModelFits",
    "atlas",
    "dask",
    "mitsuba",
    "plot",
    "oat",
    "Conductor",
    "Dielectric",
    "Diffuse",
    "Param",
    "Stack",
    "Spectrum",
    "RGB_WAVELENGTHS",
    "to_xyz",
    "to_srgb",
    "xyz_weights",
    "family",
    "materials",
    "measured",
    "optics",
    "reference",
    "jacobian_reflect",
    "jacobian_refract",
    "__version__",
    "render",
    "gallery",
    "DirectionalLight",
    "PointLight",
    "Mesh",
    "EnvironmentLight",
    "sky",
    "save_image",
    "read_image",
]
