"""The investigator's timeline: every logged event of one robot or one human over a window, in time order."""
