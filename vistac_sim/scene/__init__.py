"""The MuJoCo scene of one object: the hand's MJCF asset (`sim_assets/hand/`) edited from the
config through `MjSpec`, the object's meshes added, compiled (`model`); index look-ups (`ids`);
and the `Grasp` that poses object and fingertips in it (`grasp`)."""
