"""``sign_flip``: the centre of some samples was reconstructed on the wrong side of the laser
plane (y = +sqrt(R^2 - r^2) instead of -sqrt(...)). Discrete: a set of sample ids. A sample
is named only when, with its y negated, its residual under the structured fit returns within
3 sigma."""
KIND = "discrete"
NAME = "sign_flip"
PARAMS = ("ids",)
DOC = "samples whose centre lies on the other side of the laser plane"
