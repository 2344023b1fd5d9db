"""General (non-work-zone) US sign recognition: red and yellow signs by colour blobs and
templates (Cahail et al., Cahail et al.), white regulatory rectangles, green guide signs and mile
markers by colour and shape.  No ROS import.
"""
from workzone_ros.core.general.config import (
    GENERAL_CLASSES,
    RED_TEMPLATES,
    GeneralConfig,
    GeneralSign,
    GeneralSignError,
)
from workzone_ros.core.general.detector import GeneralSignDetector, check_image

__all__ = ['GeneralSign', 'GeneralConfig', 'GeneralSignDetector', 'GeneralSignError',
           'GENERAL_CLASSES', 'RED_TEMPLATES', 'check_image']
