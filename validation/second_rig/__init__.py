"""A second simulator of an idle-rattle rig, structurally different from rattlefit's model
(see its README), and the validation sets drawn from it (:mod:`.validation_set`)."""
