"""The application layer: the workflows that a command runs, built on the core packages.

* :mod:`~jointid.app.records` -- one record through the chain, and all records of a campaign;
* :mod:`~jointid.app.workflow` -- a campaign identified: the chain from the records to the result;
* :mod:`~jointid.app.campaign_fit` -- every pooled fit of a campaign: groups, damping laws, preload models, power laws;
* :mod:`~jointid.app.campaign_result` -- what an identification returns (``CampaignResult``, results.json);
* :mod:`~jointid.app.model_checks` -- model selection (``--terms auto``) and adequacy per preload;
* :mod:`~jointid.app.reprediction` -- each group's measured FRF re-predicted by harmonic balance, loop errors;
* :mod:`~jointid.app.channel_delay` -- the channel-delay step of an identification;
* :mod:`~jointid.app.broadband_records` -- multisine and random records of a campaign;
* :mod:`~jointid.app.backbones` -- backbones and joint laws of a campaign (stepped sine, ring-downs, models);
* :mod:`~jointid.app.synthesis` -- simulated campaigns from a TOML configuration;
* :mod:`~jointid.app.paper_example` -- the seed paper's numerical example (Section 4);
* :mod:`~jointid.app.demo` -- the seed's experiment on the virtual rig;
* :mod:`~jointid.app.public_data` -- worked examples on the public measured data sets;
* :mod:`~jointid.app.public_backbones` -- backbones of the public data sets.
"""
