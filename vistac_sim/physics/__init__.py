"""The press and what makes its labels trustworthy: drive both fingertips into the object and
settle (`press`), check the solve and the force against the friction cone (`checks`), and look up
the surface normal of the full-resolution mesh at each contact (`normals`)."""
