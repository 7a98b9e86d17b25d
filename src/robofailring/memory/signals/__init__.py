"""The signal memory: the robot's own signals as a second modality beside the cameras (docs/signals.md), and the
one home of the modalities' names and the split of views between them (`modality.py`)."""
