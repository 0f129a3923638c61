"""The orthographic top view: MuJoCo's renderer on the model's camera (`topview`), exact pixel
boxes of the fingers (`boxes`), deterministic PNG bytes (`png`), and the render request of the
image effects (`shot.Shot`: sampled parameters; `shot_render`: drawing them)."""
