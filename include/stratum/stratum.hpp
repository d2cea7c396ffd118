// stratum/stratum.hpp -- every stratum module. Each header also compiles on its own; include only
// the one you need (e.g. <stratum/dipole.hpp>) to pull in nothing else.
#pragma once

// Numerics
#include "azimuthal_quadrature.hpp"
#include "legendre.hpp"
#include "quadrature.hpp"

// Pointwise physics
#include "fresnel.hpp"
#include "henyey_greenstein.hpp"
#include "interface.hpp"
#include "microfacet.hpp"
#include "vec3.hpp"

// Discretization and the layer solver
#include "adding.hpp"
#include "interface_operators.hpp"
#include "layer.hpp"
#include "planner.hpp"
#include "slab.hpp"
#include "tabulated_bsdf.hpp"
#include "pbrt_bsdf.hpp"

// Diffusion
#include "bssrdf.hpp"
#include "dipole.hpp"
#include "lambert_w.hpp"
#include "single_scattering.hpp"
