"""Model zoo: the reference study's CNNs and efficient modern baselines, registered by name.

timm-style registry (`registry`): a builder function is registered with
`@register_model("slug")`, and `create_model(name, in_channels, out_features)` builds it from a
string, so that the CLI, the trainer and a tuner pick models by name. A new model is a builder in
a module of this package (imported below) with that decorator.

- `study`: every architecture of the study (docs/study.md section 7): plain conv/max-pool stacks
  with a ReLU after every convolution and hidden FC layer and the head FC(f, w) -> ReLU ->
  FC(w, w) -> ReLU -> FC(w, 2). The rows the study's tables got wrong (SchoeConv100-V1, -V5,
  SchoeConv227-V1, -V2) use the reconstruction given in docs/study.md.
- `baselines`: efficient CPU-sized baselines (not in the study): `resnet-tiny` (0.31 M
  parameters, 60 M MACs at 227 px) and `mobilenetv2-tiny` (0.25 M, 32 M MACs).
- `pinch`: the default model, `pinchnet` (a CoordConv CNN on one fingertip crop, 48 px) inside
  `PinchModel`, which predicts each finger's contact point and normal and composes the label
  from them (closing axis, friction cone).
- `tipnet`: the previous default, a small CNN on one finger's fingertip crop (48 px, 7.8 M
  MACs), and `PerFinger`, which runs any model on every finger's crop with shared weights.
- `macs`: `count_macs`, multiply-accumulates of Conv2d and Linear layers for one image.
- `command`: `vistac models`, the table of the registry.

Every model carries `input_size` (100 or 227), `in_channels`, `fc_in` (f, the input width of the
first FC layer) and `fc_width` (w, the hidden FC width; None for the baselines, whose head is a
single linear layer).
"""

# Registration order is the order of `list_models()` and `vistac models`: the study first.
from vistac_learn.models import study  # noqa: F401, I001  (each module registers its models)
from vistac_learn.models import baselines  # noqa: F401
from vistac_learn.models import tipnet  # noqa: F401
from vistac_learn.models import pinch  # noqa: F401
from vistac_learn.models.macs import count_macs
from vistac_learn.models.registry import create_model, list_models, model_info, register_model

__all__ = ["count_macs", "create_model", "list_models", "model_info", "register_model"]
