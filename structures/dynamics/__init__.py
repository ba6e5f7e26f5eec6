"""Time histories of a shear building on isolators: the Newmark + Newton kernel templates (1-D and
plan, on one chain core), their named records, the public verbs and the energy balance."""
