"""One logger per panel of a recording: cameras, scores, memory map, neighbours, success contrast, report."""
