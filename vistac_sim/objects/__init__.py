"""Objects on the table: procedural outlines extruded upwards, or user meshes, each with its
convex collision pieces (`library` builds them; `outlines`, `meshes`, `decomposition` are the
parts)."""
