"""The verbs that record, and the one robofailring command assembled from every verb app."""
