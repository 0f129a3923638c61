"""The orthographic top view: MuJoCo's renderer on the scene's camera (`topview`), exact pixel
boxes of the fingers (`boxes`), deterministic PNG bytes (`png`), and the render request of the
image effects (`view`: sampled parameters; `view_render`: drawing them)."""
