"""Rounds of found pairs: a solution is replayed in MuJoCo, the close pairs it finds
become TO pairs (:mod:`.found_pairs`), and the problem is solved again with them until no
round adds one (:mod:`.search`)."""
