"""Ch.5 perception: the hand-centric action detector (Sec. 5.2.1) classifying 45-frame segments of the hand track and
the hand crop into the 18 assembly actions of Table 5.1; ``conf/perception/<name>.yaml`` selects the method (the
thesis' LSTM-FCN + CNN or a baseline of 5.4.1)."""

from hrc_lab.perception.configs import PERCEPTIONS

__all__ = ["PERCEPTIONS"]
