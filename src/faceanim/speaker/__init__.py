"""The speaker's articulatory model (the ICP clone's): built from a speech video (:mod:`.build`), a
linear map from a few parameters to the lips', jaw's and cheeks' points and their FAPs, and the
interpretation of received FAP streams through it (:class:`SpeakerModel`); kept in a versioned
``.npz`` (:mod:`.speakerfile`).

>>> import faceanim.speaker as speaker
>>> speaker.DEFAULT_RIDGE
0.001
"""

from .analysis import CloneAnalyser
from .appearance import Appearance, read_appearance, write_appearance
from .build import METHODS, build_model, mobile_names, reconstruction_error
from .colour import ColourModel
from .model import DEFAULT_RIDGE, SpeakerModel, fap_measurement
from .mouthmesh import analysis_mesh
from .speakerfile import SPEAKER_VERSION, read_speaker, refusals_named, write_speaker

__all__ = ["SpeakerModel", "build_model", "mobile_names", "reconstruction_error", "fap_measurement", "read_speaker",
           "refusals_named", "write_speaker", "DEFAULT_RIDGE", "METHODS", "SPEAKER_VERSION",
           "Appearance", "ColourModel", "read_appearance", "write_appearance", "CloneAnalyser", "analysis_mesh"]
