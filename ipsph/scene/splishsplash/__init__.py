"""SPlisHSPlasH JSON scenes -> ipsph scenes.

`scene_dict(path)` converts a SPlisHSPlasH scene (both the current layout, with solver blocks
"DFSPH" / "Projective Fluids" in Configuration and viscosity in "Materials", and the 2.0.0
layout, everything flat in "Configuration") into ipsph's TOML dict form plus one warning
string listing every key that is not supported. `ipsph.scene.load_scene` validates that dict
with the TOML rules. Keys that would make a different simulation (emitters, dynamic
bodies, dense sampling, other pressure solvers, multiphase) are refused with a ConfigError;
keys that only affect visuals, caching or secondary physics are reported in the warning.

FluidBlocks: SPlisHSPlasH 2.x (`SceneLoader::readScene`) applies the block's transform to its
corners component-wise, min' = scale * start + translation, max' = scale * end + translation,
and `SimulatorBase::createFluidBlocks` then fills round((max' - min') / 2r) - 1 particles per
axis from min' + 2r. We store min'/max' with an identity transform, so the sampler only does the
lattice (DamBreakModel: 19 x 19 x 19 = 6,859 particles).
"""

from __future__ import annotations

from .importer import DEFAULT_END_TIME, scene_dict
from .notes import IMPORT_NOTES

__all__ = ["scene_dict", "IMPORT_NOTES", "DEFAULT_END_TIME"]
