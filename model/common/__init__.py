"""What every room of the model uses: the one error hierarchy for bad input, temporary files removed on
a signal, rotations (exponential map, projection, distances) and the statistics of a least-squares
fit (covariance, deletion tests, tail probabilities).
"""
