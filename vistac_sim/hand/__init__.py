"""The hand and one object as a MuJoCo model: the hand's MJCF asset (`sim_assets/hand/`) edited
from the config through `MjSpec` (`HandCfg`, `config`), the object's meshes added, compiled
(`model.compile_model`); index look-ups into the compiled model (`ids.ModelIds`); and the `Grasp`
that poses object and fingertips in it (`grasp`)."""
