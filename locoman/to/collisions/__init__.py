"""The collision geometry of the TO (paper A, Sec. IV-D): the robot's spheres
(:mod:`.spheres`), the objects' boxes and what they rest on (:mod:`.boxes`), and the
collision pairs a solve carries (:mod:`.pairs`). The penetration equations (11)-(13) and
their compiled kinds are in :mod:`locoman.to.terms.collisions`."""
