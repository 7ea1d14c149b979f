"""jointid.io: records and campaigns in, results out; nothing is guessed silently.

* :mod:`jointid.io.campaign` -- the campaign contract (``campaign.toml`` + records);
* :mod:`jointid.io.channels` -- :class:`Channels`, one validated record in memory;
* :mod:`jointid.io.uff`, :mod:`jointid.io.matlab`, :mod:`jointid.io.hdf5` -- UFF 58
  (ASCII and binary), MAT (plain and LMS Test.Lab), HDF5;
* :mod:`jointid.io.importer` -- lab exports to a campaign folder (``jointid import``);
* :mod:`jointid.io.datasets` -- the public data sets in ``../shared/data``;
* :mod:`jointid.io.results` -- atomic writing of JSON, CSV and figures.
"""

from .campaign import Campaign, RecordSpec, load_campaign, read_record, write_campaign, write_csv_record
from .channels import Channels, validate_channels
from .importer import import_campaign

__all__ = ["Campaign", "RecordSpec", "load_campaign", "read_record", "write_campaign", "write_csv_record",
           "Channels", "validate_channels", "import_campaign"]
