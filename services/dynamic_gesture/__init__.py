"""dynamic-gesture: strokes cut out of the hand motion, classified by ProMP templates and DTW."""
