"""Computer vision of bench recordings: region of interest, detection, tracking, flow, markers."""
