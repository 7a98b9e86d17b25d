"""The jobs that record: replay, compare, review, explain, compare-encoders and the demo."""
