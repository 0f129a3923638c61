"""Data for learning: the study's image variants (`variants`), computed once per dataset and
cached (`cache`), and the (configuration, rotation) pairs the trainer and evaluator iterate
(`pairs`). Reading a dataset is `vistac.dataset.open_tables`."""
